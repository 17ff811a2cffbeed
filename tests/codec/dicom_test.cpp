// The DICOM reader on series written here with GDCM from a phantom in Hounsfield units: slice
// order from positions, rescaling, spacing, series selection, compressed transfer syntaxes, and
// every refusal (each one line naming the file or the series).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>

#include "support/dicom_writer.hpp"
#include "support/format_error_expect.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::DicomSlice;
using voxwall::test::DicomSyntax;
using voxwall::test::EnhancedFrame;
using voxwall::test::EnhancedImage;
using voxwall::test::expectFormatError;
using voxwall::test::TempDir;
using voxwall::test::writeDicom;
using voxwall::test::writeEnhancedDicom;

namespace {

constexpr int kW = 24, kH = 20, kD = 9;

// A head-like phantom in HU: air, a soft-tissue ellipse with a bone shell, and a bright marker
// at (3, 4, 2) so that any mirroring or slice reordering shows.
std::int16_t phantom(int x, int y, int z) {
  if (x == 3 && y == 4 && z == 2) return 2500;
  const double dx = (x - 11.5) / 10.0, dy = (y - 9.5) / 8.0;
  const double r = dx * dx + dy * dy;
  if (r > 1) return -1000;
  if (r > 0.7) return std::int16_t(900 + 10 * z);
  return std::int16_t(40 + x - y + 3 * z);
}

struct Series {
  glm::dvec3 origin{-12.0, 30.0, 100.0};
  glm::dvec3 step{0, 0, -2.5};  // position of slice k: origin + k * step (feet first: z falls)
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};
  double slope = 2, intercept = -1024;
  bool isUnsigned = true;
  std::string uid = "1.2.826.0.1.3680043.2.1125.7";
  std::string description = "head CT";
  DicomSyntax syntax = DicomSyntax::ExplicitLittle;
  int depth = kD;
  glm::ivec2 shiftPerSlice{0, 0};  // stored slice k holds the phantom moved by -k * this
  int positionDecimals = -1;       // DicomSlice::positionDecimals
};

// Writes a series of `s.depth` slices under `dir` with shuffled file names and instance
// numbers; slice k holds phantom z = k, stored as (HU - intercept) / slope.
std::vector<std::string> writeSeries(const std::filesystem::path& dir, const Series& s,
                                     unsigned seed = 7) {
  std::filesystem::create_directories(dir);
  std::vector<int> order(std::size_t(s.depth));
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(seed));
  std::vector<std::string> files;
  for (int k = 0; k < s.depth; ++k) {
    DicomSlice slice;
    slice.columns = kW, slice.rows = kH;
    slice.isUnsigned = s.isUnsigned;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const int px = x + k * s.shiftPerSlice.x, py = y + k * s.shiftPerSlice.y;
        const int hu = px < kW && py < kH ? phantom(px, py, k) : -1000;
        slice.pixels.push_back(std::int16_t(std::lround((hu - s.intercept) / s.slope)));
      }
    slice.position = s.origin + double(k) * s.step;
    slice.orientation = s.orientation;
    slice.pixelSpacing = {0.7, 0.6};
    slice.slope = s.slope, slice.intercept = s.intercept;
    slice.seriesUid = s.uid, slice.description = s.description;
    slice.instance = order[std::size_t(k)] + 1;
    slice.syntax = s.syntax;
    slice.positionDecimals = s.positionDecimals;
    const auto file = (dir / ("IM" + std::to_string(order[std::size_t(k)] * 37 % 101))).string();
    writeDicom(file, slice);
    files.push_back(file);
  }
  return files;
}

// The phantom's HU at voxel (x, y, z) of a volume read back (slices ascending along the normal:
// for the default series, which steps down in z, slice z of the volume is phantom slice D-1-z).
double valueAt(const Volume& v, int x, int y, int z) { return v.valueAt(v.index(x, y, z)); }

}  // namespace

TEST(Dicom, SortsShuffledSlicesByPositionAndAppliesTheRescale) {
  TempDir dir;
  writeSeries(dir.root() / "ct", Series{});
  EXPECT_EQ(volumeFormatOf(dir.path("ct")), VolumeFormat::Dicom);
  const Volume v = readVolume(dir.path("ct"));
  ASSERT_EQ(v.dims, glm::ivec3(kW, kH, kD));
  EXPECT_EQ(v.type, ScalarType::Int16);  // uint16 stored, slope 2, intercept -1024: HU in int16
  EXPECT_DOUBLE_EQ(v.spacing.x, 0.7);
  EXPECT_DOUBLE_EQ(v.spacing.y, 0.6);
  EXPECT_NEAR(v.spacing.z, 2.5, 1e-9);  // from the positions
  int wrong = 0;
  for (int z = 0; z < kD; ++z)
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        // The series steps down in z, its normal points up: ascending order reverses it.
        const int hu = phantom(x, y, kD - 1 - z);
        // Stored values were rounded to the slope of 2.
        wrong += std::abs(valueAt(v, x, y, z) - hu) > 1;
      }
  EXPECT_EQ(wrong, 0);
  EXPECT_NEAR(valueAt(v, 3, 4, kD - 1 - 2), 2500, 1);
  EXPECT_NEAR(v.valueMin, -1000, 1);
  // Voxels stay as stored (columns, rows, slices up the normal); the matrix places them: rows
  // along +x (L), columns along +y (P), slices up +z (S), from the lowest slice's position.
  EXPECT_EQ(orientationLetters(v.orientation.direction), "LPS");
  const Series s;
  const glm::dvec3 lowest = s.origin + double(kD - 1) * s.step;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(v.orientation.origin[i], lowest[i], 1e-9);
}

TEST(Dicom, AFractionalRescaleGivesFloatAndSignedStorageStaysExact) {
  TempDir dir;
  Series s;
  s.slope = 0.5, s.intercept = -1000.25, s.isUnsigned = false;
  writeSeries(dir.root() / "f", s);
  const Volume f = readVolume(dir.path("f"));
  EXPECT_EQ(f.type, ScalarType::Float32);
  // Stored values are round((hu + 1000.25) / 0.5): every HU comes back to within 0.25.
  EXPECT_NEAR(valueAt(f, 3, 4, kD - 1 - 2), 2500, 0.25);
  EXPECT_NEAR(valueAt(f, 12, 10, 0), phantom(12, 10, kD - 1), 0.25);

  Series plain;
  plain.slope = 1, plain.intercept = 0, plain.isUnsigned = false;
  writeSeries(dir.root() / "p", plain);
  const Volume p = readVolume(dir.path("p"));
  EXPECT_EQ(p.type, ScalarType::Int16);
  EXPECT_EQ(valueAt(p, 3, 4, kD - 1 - 2), 2500);
}

TEST(Dicom, AnObliqueSeriesIsSortedAlongItsOwnNormal) {
  TempDir dir;
  Series s;
  // Rows along (cos 30, sin 30, 0), columns along z: the normal is (sin 30, -cos 30, 0) ...
  const double c = std::cos(M_PI / 6), sn = std::sin(M_PI / 6);
  s.orientation = {c, sn, 0, 0, 0, 1};
  // ... and the slices step backwards along it, 1.5 mm apart.
  s.step = -1.5 * glm::dvec3(sn, -c, 0);
  writeSeries(dir.root() / "o", s);
  const Volume v = readVolume(dir.path("o"));
  EXPECT_NEAR(v.spacing.z, 1.5, 1e-3);
  EXPECT_NEAR(valueAt(v, 3, 4, kD - 1 - 2), 2500, 1);
  // The matrix is the series' own: rows, columns, and the normal the slices were sorted along.
  const glm::dvec3 row(c, sn, 0), column(0, 0, 1), normal(sn, -c, 0);
  for (int r = 0; r < 3; ++r) {
    EXPECT_NEAR(v.orientation.direction[0][r], row[r], 1e-6);
    EXPECT_NEAR(v.orientation.direction[1][r], column[r], 1e-6);
    EXPECT_NEAR(v.orientation.direction[2][r], normal[r], 1e-6);
  }
  const glm::dvec3 first = s.origin + double(kD - 1) * s.step;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(v.orientation.origin[i], first[i], 1e-6);
}

TEST(Dicom, CompressedTransferSyntaxesDecodeToTheSameVoxels) {
  TempDir dir;
  writeSeries(dir.root() / "plain", Series{});
  const Volume plain = readVolume(dir.path("plain"));
  for (DicomSyntax syntax : {DicomSyntax::Rle, DicomSyntax::JpegLs, DicomSyntax::JpegLossless,
                             DicomSyntax::ImplicitLittle}) {
    Series s;
    s.syntax = syntax;
    const auto sub = dir.root() / ("syntax" + std::to_string(int(syntax)));
    writeSeries(sub, s);
    const Volume v = readVolume(sub.string());
    EXPECT_EQ(v.data, plain.data) << "transfer syntax " << int(syntax);
  }
}

TEST(Dicom, SeveralSeriesAreListedAndOneIsPickedByUid) {
  TempDir dir;
  writeSeries(dir.root() / "mixed", Series{});
  Series scout;
  scout.uid = "1.2.826.0.1.3680043.2.1125.9";
  scout.description = "scout";
  scout.depth = 3;
  writeSeries(dir.root() / "mixed" / "scout", scout);
  expectFormatError([&] { readVolume(dir.path("mixed")); }, dir.path("mixed"), "holds 2 series");
  expectFormatError([&] { readVolume(dir.path("mixed")); }, dir.path("mixed"),
                    "1.2.826.0.1.3680043.2.1125.9 \"scout\" (CT, 3 files, 24x20)");
  const auto list = listDicomSeries(dir.path("mixed"));
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].files, kD);
  ReadOptions pick;
  pick.dicom.series = scout.uid;
  EXPECT_EQ(readVolume(dir.path("mixed"), pick).dims, glm::ivec3(kW, kH, 3));
  pick.dicom.series = "1.2.3";
  expectFormatError([&] { readVolume(dir.path("mixed"), pick); }, dir.path("mixed"),
                    "holds no series 1.2.3");
}

TEST(Dicom, AMissingSliceUnequalGapsAndDuplicatesAreNamed) {
  TempDir dir;
  auto files = writeSeries(dir.root() / "missing", Series{});
  std::filesystem::remove(files[4]);
  expectFormatError([&] { readVolume(dir.path("missing")); }, dir.path("missing"),
                    "1 slice is missing");

  Series uneven;
  uneven.step = {0, 0, 2.0};
  files = writeSeries(dir.root() / "uneven", uneven);
  DicomSlice odd;
  odd.columns = kW, odd.rows = kH, odd.pixels.assign(kW * kH, 0);
  odd.seriesUid = uneven.uid;
  odd.position = uneven.origin + glm::dvec3(0, 0, 2.0 * kD + 0.7);  // 2.7 mm after the last
  odd.pixelSpacing = {0.7, 0.6};
  writeDicom(dir.path("uneven/odd"), odd);
  expectFormatError([&] { readVolume(dir.path("uneven")); }, dir.path("uneven"), "unequal gaps");

  // Where the first slice already is: one position repeats, the others do not (not a time
  // series, whose every position repeats as often).
  odd.position = uneven.origin;
  writeDicom(dir.path("uneven/odd"), odd);
  expectFormatError([&] { readVolume(dir.path("uneven")); }, dir.path("uneven"),
                    "repeats its positions unequally: 2 slices at the position of ");
}

TEST(Dicom, MixedSizesAndOrientationsNameTheFile) {
  TempDir dir;
  Series s;
  writeSeries(dir.root() / "sizes", s);
  DicomSlice small;
  small.columns = 8, small.rows = 8, small.pixels.assign(64, 0);
  small.seriesUid = s.uid;
  small.position = s.origin + double(kD) * s.step;
  writeDicom(dir.path("sizes/small"), small);
  expectFormatError([&] { readVolume(dir.path("sizes")); }, dir.path("sizes/small"), "is 8x8");

  writeSeries(dir.root() / "turned", s);
  DicomSlice turned;
  turned.columns = kW, turned.rows = kH, turned.pixels.assign(kW * kH, 0);
  turned.seriesUid = s.uid;
  turned.position = s.origin + double(kD) * s.step;
  turned.orientation = {0, 1, 0, 1, 0, 0};
  writeDicom(dir.path("turned/turned"), turned);
  expectFormatError([&] { readVolume(dir.path("turned")); }, dir.path("turned/turned"),
                    "oriented differently");
  // Where another slice lies too (a three-plane localizer's planes cross): still the orientation,
  // not a repeated position.
  turned.position = s.origin;
  writeDicom(dir.path("turned/turned"), turned);
  expectFormatError([&] { readVolume(dir.path("turned")); }, dir.path("turned/turned"),
                    "oriented differently");
}

TEST(Dicom, AGantryTiltIsRefusedOrResampledOntoABox) {
  TempDir dir;
  Series s;
  s.step = {0, 0.6, 2.5};    // each slice moves one row (0.6 mm) along y: a 13.5 degree tilt
  s.shiftPerSlice = {0, 1};  // and holds the phantom moved back by one row per slice
  s.step.z = 2.5;
  writeSeries(dir.root() / "tilt", s);
  expectFormatError([&] { readVolume(dir.path("tilt")); }, dir.path("tilt"), "gantry tilt of 13.5");
  ReadOptions resample;
  resample.dicom.resampleTilt = true;
  const Volume v = readVolume(dir.path("tilt"), resample);
  ASSERT_EQ(v.dims, glm::ivec3(kW, kH, kD));
  // Slice z (ascending z here) was stored moved by z rows; resampled, it is the phantom again
  // wherever the stored slice covered it.
  int wrong = 0, checked = 0;
  for (int z = 0; z < kD; ++z)
    for (int y = z; y < kH; ++y)
      for (int x = 0; x < kW; ++x, ++checked)
        wrong += std::abs(valueAt(v, x, y, z) - phantom(x, y, z)) > 1;
  EXPECT_EQ(wrong, 0) << "of " << checked;
  EXPECT_NEAR(valueAt(v, 3, 4, 2), 2500, 1);
}

TEST(Dicom, AMultiFrameFileIsOneVolume) {
  TempDir dir;
  DicomSlice m;
  m.columns = kW, m.rows = kH, m.frames = 4;
  m.isUnsigned = true, m.intercept = -1000;
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) m.pixels.push_back(std::int16_t(phantom(x, y, z) + 1000));
  m.pixelSpacing = {0.5, 0.5};
  m.sliceSpacing = 1.25;
  writeDicom(dir.path("multi.dcm"), m);
  const Volume v = readVolume(dir.path("multi.dcm"));
  ASSERT_EQ(v.dims, glm::ivec3(kW, kH, 4));
  EXPECT_EQ(valueAt(v, 3, 4, 2), 2500);
  EXPECT_EQ(valueAt(v, 12, 10, 3), phantom(12, 10, 3));
  EXPECT_DOUBLE_EQ(v.spacing.x, 0.5);
}

namespace {

// An enhanced MR of the phantom, oblique (13 degrees about x), 4 x 3.5 mm pixels and 6 mm apart,
// as two images (magnitude, and a field map stored at half a unit with an offset) whose frames
// are interleaved and, within each image, out of order.
struct EnhancedMr {
  glm::dvec3 row{1, 0, 0}, column{0, std::cos(0.2269), std::sin(0.2269)};
  glm::dvec3 normal = glm::cross(row, column);
  glm::dvec3 origin{-40, 20, 10};
  double gap = 6;
  EnhancedImage image() const {
    EnhancedImage e;
    e.columns = kW, e.rows = kH;
    e.orientation = {row.x, row.y, row.z, column.x, column.y, column.z};
    e.pixelSpacing = {4, 3.5};
    e.sliceThickness = 6;
    const int order[kD] = {4, 0, 7, 2, 8, 1, 6, 3, 5};
    for (const int z : order)
      for (const std::uint32_t type : {1u, 2u}) {
        EnhancedFrame f;
        f.position = origin + double(z) * gap * normal;
        f.imageIndex = type, f.stackPosition = std::uint32_t(z + 1);
        if (type == 2) {
          f.frameType = "ORIGINAL\\PRIMARY\\B0_MAP\\NONE";
          f.slope = 0.5, f.intercept = -100;  // value = stored / 2 - 100
        }
        for (int y = 0; y < kH; ++y)
          for (int x = 0; x < kW; ++x)
            f.pixels.push_back(type == 1 ? phantom(x, y, z)
                                         : std::int16_t(2 * (phantom(x, y, z) + 100) + 1));
        e.frames.push_back(std::move(f));
      }
    return e;
  }
};

}  // namespace

// The geometry of an enhanced image is in its functional groups, not at the top level; a file
// of two images is never stacked into one volume: it is refused with their list, and each one
// is read whole with --dicom-image.
TEST(Dicom, AnEnhancedMrOfTwoImagesIsListedAndEachReadsFromItsFunctionalGroups) {
  TempDir dir;
  const EnhancedMr mr;
  writeEnhancedDicom(dir.path("mr.dcm"), mr.image());
  expectFormatError([&] { readVolume(dir.path("mr.dcm")); }, dir.path("mr.dcm"),
                    "holds 2 images in its 18 frames (1: dimension index 1, stack 1, frame type "
                    "ORIGINAL\\PRIMARY\\M_FFE\\M_FFE (9 frames); 2: dimension index 2, stack 1, "
                    "frame type ORIGINAL\\PRIMARY\\B0_MAP\\NONE (9 frames)); read one with "
                    "--dicom-image N");
  for (const int image : {1, 2}) {
    ReadOptions options;
    options.dicom.image = image;
    const Volume v = readVolume(dir.path("mr.dcm"), options);
    ASSERT_EQ(v.dims, glm::ivec3(kW, kH, kD));
    EXPECT_DOUBLE_EQ(v.spacing.x, 4.0);
    EXPECT_DOUBLE_EQ(v.spacing.y, 3.5);
    EXPECT_NEAR(v.spacing.z, 6.0, 1e-4);
    int wrong = 0;
    for (int z = 0; z < kD; ++z)
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
          wrong +=
              std::abs(valueAt(v, x, y, z) - (phantom(x, y, z) + (image == 2 ? 0.5 : 0))) > 1e-3;
    EXPECT_EQ(wrong, 0) << "image " << image;
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(v.orientation.direction[0][i], mr.row[i], 1e-5);
      EXPECT_NEAR(v.orientation.direction[1][i], mr.column[i], 1e-5);
      EXPECT_NEAR(v.orientation.direction[2][i], mr.normal[i], 1e-5);
      EXPECT_NEAR(v.orientation.origin[i], mr.origin[i], 1e-4);
    }
  }
  EXPECT_EQ(readVolume(dir.path("mr.dcm"),
                       [] {
                         ReadOptions o;
                         o.dicom.image = 2;
                         return o;
                       }())
                .type,
            ScalarType::Float32);  // half-unit values
  ReadOptions third;
  third.dicom.image = 3;
  expectFormatError([&] { readVolume(dir.path("mr.dcm"), third); }, dir.path("mr.dcm"),
                    "holds 2 images; --dicom-image 3 is not one of them");
}

// An enhanced CT of one image with a rescale of its own per frame and no Dimension Index
// Sequence; a frame missing from its stack is named as a missing slice is.
TEST(Dicom, AnEnhancedCtWithPerFrameRescaleIsOneVolume) {
  TempDir dir;
  EnhancedMr geometry;
  EnhancedImage ct = geometry.image();
  ct.modality = "CT";
  ct.dimensionIndex = false;
  std::vector<EnhancedFrame> frames;
  for (EnhancedFrame& f : ct.frames) {
    if (f.imageIndex != 1) continue;
    f.frameType = "ORIGINAL\\PRIMARY\\AXIAL";
    const int z = int(f.stackPosition) - 1;
    f.intercept = -1024 + 10 * z;  // each frame its own offset
    for (auto& p : f.pixels) p = std::int16_t(p - f.intercept);
    frames.push_back(f);
  }
  ct.frames = frames;
  writeEnhancedDicom(dir.path("ct.dcm"), ct);
  const Volume v = readVolume(dir.path("ct.dcm"));
  ASSERT_EQ(v.dims, glm::ivec3(kW, kH, kD));
  EXPECT_EQ(v.type, ScalarType::Int16);
  int wrong = 0;
  for (int z = 0; z < kD; ++z)
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) wrong += valueAt(v, x, y, z) != phantom(x, y, z);
  EXPECT_EQ(wrong, 0);
  ct.frames.erase(ct.frames.begin() + 3);  // phantom slice 3 (the fourth of `order`)
  writeEnhancedDicom(dir.path("gap.dcm"), ct);
  expectFormatError([&] { readVolume(dir.path("gap.dcm")); }, dir.path("gap.dcm"),
                    "1 slice is missing");
}

// A scanner that writes its positions to 0.1 mm (as a 2001 MR series does): on an oblique normal
// the gaps differ by up to 0.12 mm at 7 mm, more than 1%, and are read as equal with a warning;
// the spacing is their fitted gap. A first file padded with megabytes of zeros after its pixels
// reads. A slice moved 0.25 mm, beyond what the rounding can do, and a missing slice are refused.
TEST(Dicom, PositionsRoundedByTheScannerAreReadAndRealGapsAreNot) {
  TempDir dir;
  Series s;
  s.depth = 20;
  const double angle = 13.0 * 3.14159265358979 / 180.0;
  s.orientation = {1, 0, 0, 0, std::cos(angle), std::sin(angle)};
  const glm::dvec3 normal(0, -std::sin(angle), std::cos(angle));
  s.step = 7.0 * normal;
  s.origin = {-12.34, 30.27, 100.81};
  s.positionDecimals = 1;
  // The gaps the rounded positions make: some more than 1% off (else the test shows nothing).
  double worst = 0;
  for (int k = 1; k < s.depth; ++k) {
    auto rounded = [&](int i) { return glm::round((s.origin + double(i) * s.step) * 10.0) / 10.0; };
    worst = std::max(worst, std::abs(glm::dot(rounded(k) - rounded(k - 1), normal) - 7.0));
  }
  ASSERT_GT(worst, 0.07);
  auto files = writeSeries(dir.root() / "rounded", s);
  {  // zero padding after the pixels of the first file
    std::ofstream pad(files[0], std::ios::binary | std::ios::app);
    const std::string zeros(std::size_t(5) << 19, '\0');
    pad.write(zeros.data(), std::streamsize(zeros.size()));
  }
  std::vector<std::string> warnings;
  ReadOptions options;
  options.dicom.warn = [&](const std::string& w) { warnings.push_back(w); };
  const Volume v = readVolume(dir.path("rounded"), options);
  ASSERT_EQ(v.dims, glm::ivec3(kW, kH, 20));
  EXPECT_NEAR(v.spacing.z, 7.0, 0.02);
  EXPECT_NEAR(valueAt(v, 3, 4, 0), phantom(3, 4, 0), 1);  // stored at a slope of 2
  EXPECT_NEAR(valueAt(v, 12, 10, 19), phantom(12, 10, 19), 1);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("its slice positions were written to 1 decimals: gaps of "),
            std::string::npos)
      << warnings[0];

  // One slice 0.25 mm off along the normal: beyond the 0.12 mm the rounding accounts for.
  Series moved = s;
  moved.uid += ".2";
  files = writeSeries(dir.root() / "moved", moved);
  DicomSlice off;
  off.columns = kW, off.rows = kH, off.pixels.assign(kW * kH, 0);
  off.seriesUid = moved.uid, off.orientation = moved.orientation;
  off.pixelSpacing = {0.7, 0.6};
  off.position = moved.origin + 20.0 * moved.step + 0.25 * normal;  // a 21st slice
  off.positionDecimals = 2;
  writeDicom(dir.path("moved/late"), off);
  expectFormatError([&] { readVolume(dir.path("moved")); }, dir.path("moved"), "unequal gaps");

  std::filesystem::remove(files[7]);
  std::filesystem::remove(dir.path("moved/late"));
  expectFormatError([&] { readVolume(dir.path("moved")); }, dir.path("moved"),
                    "1 slice is missing");
}

TEST(Dicom, CorruptFilesAreRefusedNamingTheFile) {
  TempDir dir;
  auto files = writeSeries(dir.root() / "cut", Series{});
  const std::string whole = voxwall::test::readFile(files[3]);
  voxwall::test::writeFile(files[3], whole.substr(0, whole.size() - 300));
  expectFormatError([&] { readVolume(dir.path("cut")); }, files[3], "is cut short");

  // The pixel data element says fewer bytes than the image needs.
  files = writeSeries(dir.root() / "short", Series{});
  std::string bytes = voxwall::test::readFile(files[5]);
  const std::string pixelTag("\xe0\x7f\x10\x00OW\x00\x00", 8);
  const auto at = bytes.rfind(pixelTag);
  ASSERT_NE(at, std::string::npos);
  const std::uint32_t shorter = kW * kH * 2 - 40;
  std::memcpy(&bytes[at + 8], &shorter, 4);
  bytes.resize(at + 12 + shorter);
  voxwall::test::writeFile(files[5], bytes);
  expectFormatError([&] { readVolume(dir.path("short")); }, files[5],
                    "its pixel data holds 920 bytes");

  // A private element that claims more bytes than the file has: refused, not allocated.
  files = writeSeries(dir.root() / "bomb", Series{});
  bytes = voxwall::test::readFile(files[1]);
  const auto pixels = bytes.rfind(pixelTag);
  ASSERT_NE(pixels, std::string::npos);
  std::string bomb("\xd1\x7f\x10\x10UN\x00\x00", 8);
  const std::uint32_t huge = 0xfffffff0u;
  bomb.append(reinterpret_cast<const char*>(&huge), 4);
  bomb += "0123";
  voxwall::test::writeFile(files[1], bytes.substr(0, pixels) + bomb + bytes.substr(pixels));
  // (Where the element lies depends on the lengths of the UIDs GDCM made for this series.)
  expectFormatError([&] { readVolume(dir.path("bomb")); }, files[1],
                    "has an element (7FD1,1010) at byte " + std::to_string(pixels) +
                        " that claims 4294967280 bytes past the end of the file");

  // Rows claiming 53,250 bytes: GDCM's scanner, reading past the end, fell back to other
  // encodings on a failed stream and aborted the program on an assertion (found by the DICOM
  // fuzz target). The elements' lengths are walked before GDCM reads them.
  files = writeSeries(dir.root() / "rows", Series{});
  bytes = voxwall::test::readFile(files[6]);
  const auto rows = bytes.find(std::string("\x28\x00\x10\x00US\x02\x00", 8));
  ASSERT_NE(rows, std::string::npos);
  bytes[rows + 6] = char(0x02), bytes[rows + 7] = char(0xd0);
  voxwall::test::writeFile(files[6], bytes);
  expectFormatError([&] { readVolume(dir.path("rows")); }, files[6],
                    "has an element (0028,0010) at byte " + std::to_string(rows) +
                        " that claims 53250 bytes past the end of the file");

  // Not a DICOM file at all, named .dcm.
  voxwall::test::writeFile(dir.path("junk.dcm"), std::string(200, 'x'));
  expectFormatError([&] { readVolume(dir.path("junk.dcm")); }, dir.path("junk.dcm"),
                    "not a DICOM Part 10 file");

  // An undefined length in the File Meta Information: GDCM (built with assertions) aborted the
  // program there; it is refused first (the DICOM fuzz target found it).
  files = writeSeries(dir.root() / "meta", Series{});
  bytes = voxwall::test::readFile(files[2]);
  const std::string undefined("\x02\x00\x01\x00OB\x00\x00\xff\xff\xff\xff", 12);
  voxwall::test::writeFile(files[2], bytes.substr(0, 132) + undefined + bytes.substr(132));
  expectFormatError([&] { readVolume(dir.path("meta")); }, files[2], "undefined length");

  // RLE pixel data whose first fragment does not start with a segment count of 1 to 15 (GDCM's
  // decoders were handed such fragments and spent gigabytes): refused before any decoding.
  Series rle;
  rle.syntax = DicomSyntax::Rle;
  files = writeSeries(dir.root() / "rle", rle);
  bytes = voxwall::test::readFile(files[4]);
  const std::string encapsulated("\xe0\x7f\x10\x00OB\x00\x00\xff\xff\xff\xff", 12);
  const std::string item("\xfe\xff\x00\xe0", 4);
  const auto pixelAt = bytes.rfind(encapsulated);
  ASSERT_NE(pixelAt, std::string::npos);
  // The basic offset table's item, then the first fragment's item: its data follows its length.
  const auto table = bytes.find(item, pixelAt + 12);
  std::uint32_t tableBytes = 0;
  std::memcpy(&tableBytes, &bytes[table + 4], 4);
  const auto fragment = table + 8 + tableBytes;
  ASSERT_EQ(bytes.compare(fragment, 4, item), 0);
  bytes[fragment + 8] = char(0);  // segment count 0
  voxwall::test::writeFile(files[4], bytes);
  expectFormatError([&] { readVolume(dir.path("rle")); }, files[4],
                    "its compressed pixel data does not start as transfer syntax "
                    "1.2.840.10008.1.2.5 does");

  // A fragment claiming 4 GiB in a file of a few KiB: GDCM would allocate it (12.7 GB and 142 s
  // for one such file, which it then accepted); the items are walked first and it is refused.
  bytes = voxwall::test::readFile(files[4]);
  const std::uint32_t claim = 0xfffffff0u;
  std::memcpy(&bytes[fragment + 4], &claim, 4);
  voxwall::test::writeFile(files[4], bytes);
  expectFormatError([&] { readVolume(dir.path("rle")); }, files[4],
                    "fragment 1 of its compressed pixel data claims 4294967280 bytes");
  // The sequence delimiter missing: the items run to the end of the file.
  bytes = voxwall::test::readFile(files[3]);
  const auto delimiter = bytes.rfind(std::string("\xfe\xff\xdd\xe0", 4));
  ASSERT_NE(delimiter, std::string::npos);
  writeSeries(dir.root() / "rle", rle);  // the other slices whole again, files[4] too
  voxwall::test::writeFile(files[3], bytes.substr(0, delimiter));
  expectFormatError([&] { readVolume(dir.path("rle")); }, files[3],
                    "before its sequence delimiter");
}

// Elements GDCM reads in a way of its own (workarounds for broken files that shift where it reads
// the rest, or an assertion that an undefined length means UN) are refused before it sees them.
TEST(Dicom, ElementsGdcmWouldMisreadAreRefused) {
  TempDir dir;
  const std::string pixelTag("\xe0\x7f\x10\x00OW\x00\x00", 8);
  std::size_t at = 0;  // where the element went
  const auto withBefore = [&](const std::string& name, const std::string& element) {
    const auto files = writeSeries(dir.root() / name, Series{});
    const std::string bytes = voxwall::test::readFile(files[2]);
    at = bytes.rfind(pixelTag);
    EXPECT_NE(at, std::string::npos);
    voxwall::test::writeFile(files[2], bytes.substr(0, at) + element + bytes.substr(at));
    return files[2];
  };
  // An OB of undefined length that is not pixel data (GDCM asserts it is UN).
  std::string file =
      withBefore("ob", std::string("\xd1\x7f\x10\x10OB\x00\x00\xff\xff\xff\xff", 12) +
                           std::string("\xfe\xff\x00\xe0\x02\x00\x00\x00xx", 10) +
                           std::string("\xfe\xff\xdd\xe0\x00\x00\x00\x00", 8));
  expectFormatError([&] { readVolume(dir.path("ob")); }, file,
                    "(7FD1,1010) at byte " + std::to_string(at) +
                        " of undefined length that is neither a sequence nor "
                        "pixel data");
  // A UL of 6 bytes (GDCM reads 4 of them in group 0009).
  file = withBefore("ul", std::string("\x09\x00\x10\x10UL\x06\x00\x01\x02\x03\x04\x05\x06", 14));
  expectFormatError(
      [&] { readVolume(dir.path("ul")); }, file,
      "(0009,1010) at byte " + std::to_string(at) + " of 6 bytes, not a whole number of UL values");
  // Pixel Data whose VR is two zero bytes: GDCM's fallback reader asserted (found by the DICOM
  // fuzz target).
  file = withBefore("pixelvr", "");
  std::string bytes = voxwall::test::readFile(file);
  bytes[at + 4] = bytes[at + 5] = '\0';
  voxwall::test::writeFile(file, bytes);
  expectFormatError([&] { readVolume(dir.path("pixelvr")); }, file,
                    "its Pixel Data is stored with a value representation other than OB, OW or UN");
  // No transfer syntax in the meta group: GDCM would guess how the data set is encoded.
  file = withBefore("nosyntax", "");
  bytes = voxwall::test::readFile(file);
  const auto syntax = bytes.find(std::string("\x02\x00\x10\x00UI", 6));
  ASSERT_NE(syntax, std::string::npos);
  const std::size_t syntaxBytes = 8 + std::uint8_t(bytes[syntax + 6]);
  voxwall::test::writeFile(file, bytes.erase(syntax, syntaxBytes));
  expectFormatError([&] { readVolume(dir.path("nosyntax")); }, file,
                    "names no Transfer Syntax UID (0002,0010)");
  // Pixel Data claiming 4 GiB: GDCM's scanner, which reads the element after the last tag it
  // looks for, allocated that (found by the DICOM fuzz target); files are checked whole first.
  file = withBefore("bigpixels", "");
  bytes = voxwall::test::readFile(file);
  const std::uint32_t claim = 0xffffff00u;
  std::memcpy(&bytes[at + 8], &claim, 4);
  voxwall::test::writeFile(file, bytes);
  expectFormatError([&] { readVolume(dir.path("bigpixels")); }, file,
                    "is cut short: its pixel data ends at byte");
  // A Recognition Code that is not ACR-NEMA's: GDCM 3.0 asserts (found by the DICOM fuzz target).
  file = withBefore("recognition", std::string("\x08\x00\x10\x00SH\x04\x00JUNK", 12));
  expectFormatError([&] { readVolume(dir.path("recognition")); }, file,
                    "has a Recognition Code (0008,0010) that is not ACR-NEMA's");
  // A public value (Slice Thickness) stored as UN of undefined length: read as items, no value.
  file = withBefore("unvalue", std::string("\x18\x00\x50\x00UN\x00\x00\xff\xff\xff\xff", 12) +
                                   std::string("\xfe\xff\xdd\xe0\x00\x00\x00\x00", 8));
  expectFormatError([&] { readVolume(dir.path("unvalue")); }, file,
                    "(0018,0050) at byte " + std::to_string(at) +
                        " stored as UN of undefined length where DICOM says it holds a value");
  // (00FF,4AA5), read by GDCM as pixel data up to the end of the file.
  file = withBefore("marker", std::string("\xff\x00\xa5\x4aOB\x00\x00\x02\x00\x00\x00xx", 14));
  expectFormatError([&] { readVolume(dir.path("marker")); }, file, "(00FF,4AA5)");
}

// The element walk that guards GDCM steps over what real files hold: an icon image sequence of
// undefined length whose pixel data is compressed fragments (bytes that are not elements).
TEST(Dicom, AnIconWithCompressedFragmentsInASequenceIsRead) {
  TempDir dir;
  const auto files = writeSeries(dir.root() / "icon", Series{});
  std::string bytes = voxwall::test::readFile(files[0]);
  const auto pixels = bytes.rfind(std::string("\xe0\x7f\x10\x00OW\x00\x00", 8));
  ASSERT_NE(pixels, std::string::npos);
  const std::string undefined("\xff\xff\xff\xff", 4), zero("\x00\x00\x00\x00", 4);
  const std::string icon = std::string("\x88\x00\x00\x02SQ\x00\x00", 8) + undefined +  // sequence
                           std::string("\xfe\xff\x00\xe0", 4) + undefined +            // item
                           std::string("\xe0\x7f\x10\x00OB\x00\x00", 8) + undefined +  // pixels
                           std::string("\xfe\xff\x00\xe0", 4) + zero +                 // offsets
                           std::string("\xfe\xff\x00\xe0\x04\x00\x00\x00\xfe\xff\x00\xe0", 12) +
                           std::string("\xfe\xff\xdd\xe0", 4) + zero +  // fragments end
                           std::string("\xfe\xff\x0d\xe0", 4) + zero +  // item end
                           std::string("\xfe\xff\xdd\xe0", 4) + zero;   // sequence end
  voxwall::test::writeFile(files[0], bytes.substr(0, pixels) + icon + bytes.substr(pixels));
  const Volume v = readVolume(dir.path("icon"));
  EXPECT_EQ(v.dims, glm::ivec3(kW, kH, kD));
  EXPECT_NEAR(valueAt(v, 3, 4, kD - 1 - 2), 2500, 1);
}

TEST(Dicom, AFolderOfImagesIsStillASliceStackAndAnEmptyOneIsRefused) {
  TempDir dir;
  std::filesystem::create_directories(dir.root() / "empty");
  EXPECT_EQ(volumeFormatOf(dir.path("empty")), VolumeFormat::SliceStack);
  writeSeries(dir.root() / "ct" / "nested" / "deeper", Series{});
  voxwall::test::writeFile(dir.path("ct/DICOMDIR"), "");
  voxwall::test::writeFile(dir.path("ct/README.txt"), "not DICOM");
  EXPECT_EQ(volumeFormatOf(dir.path("ct")), VolumeFormat::Dicom);
  // A DICOMDIR stands for the folder it lies in; files without 'DICM' are left out.
  EXPECT_EQ(readVolume(dir.path("ct/DICOMDIR")).dims, glm::ivec3(kW, kH, kD));
}
