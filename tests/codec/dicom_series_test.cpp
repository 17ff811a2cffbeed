// DICOM series whose positions repeat, written here with GDCM as scanners write them: an fMRI run
// ordered only by its instance numbers, cine phases ordered by trigger time with shuffled
// instance numbers, an enhanced file of two time points and a folder of enhanced files, one per
// time point, read as time series; two echoes and two b-values listed as images and never read
// as time; repeats that are unequal or that nothing tells apart refused in one line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <random>
#include <voxwall/codec/volume_io.hpp>

#include "support/dicom_writer.hpp"
#include "support/format_error_expect.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::DicomSlice;
using voxwall::test::expectFormatError;
using voxwall::test::TempDir;

namespace {

constexpr int kCols = 12, kRows = 10, kPositions = 6;

// The value a run's step `t` holds at (x, y, z): each step and each position differs, and a
// marker at (2, 3) on position 1 shows any mirroring.
std::int16_t runValue(int x, int y, int z, int t) {
  if (x == 2 && y == 3 && z == 1) return std::int16_t(3000 + t);
  return std::int16_t(10 * x - 7 * y + 40 * z + 500 * t);
}

// 13 degrees oblique about x, 4 mm apart.
const double kTilt = 13.0 * 3.14159265358979 / 180.0;
const glm::dvec3 kRow{1, 0, 0}, kColumn{0, std::cos(kTilt), std::sin(kTilt)};
const glm::dvec3 kNormal = glm::cross(kRow, kColumn);
const glm::dvec3 kOrigin{-20, 15, 40};
constexpr double kGap = 4;

struct RunSlice {
  int z = 0, t = 0;
  DicomSlice slice;
};

// Every position of every step as a slice: MR, oblique, with the run's values.
std::vector<RunSlice> runSlices(int steps) {
  std::vector<RunSlice> out;
  for (int t = 0; t < steps; ++t)
    for (int z = 0; z < kPositions; ++z) {
      RunSlice r;
      r.z = z, r.t = t;
      DicomSlice& s = r.slice;
      s.modality = "MR";
      s.columns = kCols, s.rows = kRows;
      for (int y = 0; y < kRows; ++y)
        for (int x = 0; x < kCols; ++x) s.pixels.push_back(runValue(x, y, z, t));
      s.position = kOrigin + double(z) * kGap * kNormal;
      s.orientation = {kRow.x, kRow.y, kRow.z, kColumn.x, kColumn.y, kColumn.z};
      s.pixelSpacing = {1.5, 2.0};
      s.acquisitionTime = "101500.000000";  // the same for all: it tells nothing apart
      s.instance = t * kPositions + z + 1;
      out.push_back(std::move(r));
    }
  return out;
}

// Writes the slices under `dir` with shuffled file names.
void writeRun(const TempDir& dir, const std::string& folder, const std::vector<RunSlice>& run) {
  std::filesystem::create_directories(dir.path(folder));
  std::vector<std::size_t> order(run.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(11));
  for (std::size_t i = 0; i < run.size(); ++i)
    voxwall::test::writeDicom(dir.path(folder + "/F" + std::to_string(order[i] * 53 % 997)),
                              run[i].slice);
}

// Step `t` of a run read back: the run's values voxel for voxel, slices along the oblique normal.
void expectStep(const Volume& v, int t, double valueOffset = 0) {
  ASSERT_EQ(v.dims, glm::ivec3(kCols, kRows, kPositions));
  EXPECT_DOUBLE_EQ(v.spacing.x, 1.5);
  EXPECT_DOUBLE_EQ(v.spacing.y, 2.0);
  EXPECT_NEAR(v.spacing.z, kGap, 1e-4);
  int wrong = 0;
  for (int z = 0; z < kPositions; ++z)
    for (int y = 0; y < kRows; ++y)
      for (int x = 0; x < kCols; ++x)
        wrong +=
            std::abs(v.valueAt(v.index(x, y, z)) - (runValue(x, y, z, t) + valueOffset)) > 1e-3;
  EXPECT_EQ(wrong, 0) << "step " << t;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(v.orientation.direction[0][i], kRow[i], 1e-5);
    EXPECT_NEAR(v.orientation.direction[1][i], kColumn[i], 1e-5);
    EXPECT_NEAR(v.orientation.direction[2][i], kNormal[i], 1e-5);
    EXPECT_NEAR(v.orientation.origin[i], kOrigin[i], 1e-4);
  }
}

}  // namespace

// An fMRI export: 6 positions x 3 volumes, nothing but the instance number orders them in time.
TEST(DicomSeries, AnFmriRunOrderedOnlyByInstanceNumberIsATimeSeries) {
  TempDir dir;
  writeRun(dir, "fmri", runSlices(3));
  expectFormatError([&] { readVolume(dir.path("fmri")); }, dir.path("fmri"),
                    "holds 3 time steps of 6 slices, ordered by instance number: a time series");
  const DicomInput input(dir.path("fmri"), {});
  ASSERT_EQ(input.steps(), 3);
  for (int t = 0; t < 3; ++t) expectStep(input.read(t), t);
  const auto images = listDicomImages(dir.path("fmri"));
  ASSERT_EQ(images.size(), 1u);
  EXPECT_EQ(images[0].slices, kPositions);
  EXPECT_EQ(images[0].steps, 3);
}

// Cine phases: the trigger time orders them (it differs a little between positions, as each is
// acquired on its own heartbeat); the instance numbers are shuffled and say nothing.
TEST(DicomSeries, PhasesOrderedByTriggerTimeWithShuffledInstanceNumbers) {
  TempDir dir;
  auto run = runSlices(4);
  std::vector<int> instances(run.size());
  std::iota(instances.begin(), instances.end(), 1);
  std::shuffle(instances.begin(), instances.end(), std::mt19937(5));
  for (std::size_t i = 0; i < run.size(); ++i) {
    run[i].slice.instance = instances[i];
    run[i].slice.triggerTime = 40.0 * run[i].t + 0.5 * run[i].z;
  }
  writeRun(dir, "cine", run);
  const DicomInput input(dir.path("cine"), {});
  ASSERT_EQ(input.steps(), 4);
  EXPECT_EQ(input.describeSteps(), "4 time steps of 6 slices, ordered by trigger time");
  for (int t = 0; t < 4; ++t) expectStep(input.read(t), t);
}

// Two echoes at every position are two images, never two time steps: listed, each read alone.
TEST(DicomSeries, TwoEchoesAreListedAsImagesAndEachReadsAlone) {
  TempDir dir;
  auto run = runSlices(2);
  for (RunSlice& r : run) r.slice.echoNumber = r.t + 1, r.slice.echoTime = 10.0 * (r.t + 1);
  writeRun(dir, "echoes", run);
  expectFormatError([&] { readVolume(dir.path("echoes")); }, dir.path("echoes"),
                    "holds 2 images in its 12 files (1: echo 1, echo time 10 (6 files); 2: echo "
                    "2, echo time 20 (6 files)); read one with --dicom-image N");
  for (const int image : {1, 2}) {
    ReadOptions options;
    options.dicom.image = image;
    expectStep(readVolume(dir.path("echoes"), options), image - 1);
  }
  const auto images = listDicomImages(dir.path("echoes"));
  ASSERT_EQ(images.size(), 2u);
  EXPECT_EQ(images[1].label, "echo 2, echo time 20");
  EXPECT_EQ(images[1].steps, 1);
}

// b-values (binary FD values) tell images apart too; repeats of each b-value are its time steps.
TEST(DicomSeries, BValuesAreImagesAndTheirRepeatsAreTimeSteps) {
  TempDir dir;
  auto run = runSlices(4);
  for (RunSlice& r : run) r.slice.bValue = r.t % 2 ? 1000 : 0;
  writeRun(dir, "dwi", run);
  expectFormatError([&] { readVolume(dir.path("dwi")); }, dir.path("dwi"),
                    "holds 2 images in its 24 files (1: b-value 0 (12 files, 2 time steps); 2: "
                    "b-value 1000 (12 files, 2 time steps))");
  DicomOptions second;
  second.image = 2;
  const DicomInput input(dir.path("dwi"), second);
  ASSERT_EQ(input.steps(), 2);
  expectStep(input.read(0), 1);
  expectStep(input.read(1), 3);
}

TEST(DicomSeries, RepeatsThatAreUnequalOrThatNothingTellsApartAreRefused) {
  TempDir dir;
  auto run = runSlices(3);
  run.erase(run.begin() + kPositions + 2);  // step 1 lacks position 2
  writeRun(dir, "short", run);
  expectFormatError([&] { readVolume(dir.path("short")); }, dir.path("short"),
                    "repeats its positions unequally: 3 slices at the position of ");
  run = runSlices(2);
  for (RunSlice& r : run) r.slice.instance = r.z + 1;  // the two volumes share their numbers
  writeRun(dir, "same", run);
  expectFormatError([&] { readVolume(dir.path("same")); }, dir.path("same"),
                    "lie at the same position and nothing tells them apart in time or as images");
}

namespace {

// An enhanced MR of the run's steps `steps`, frames interleaved and out of order.
voxwall::test::EnhancedImage enhancedRun(const std::vector<int>& steps, bool temporalIndex) {
  voxwall::test::EnhancedImage e;
  e.columns = kCols, e.rows = kRows;
  e.orientation = {kRow.x, kRow.y, kRow.z, kColumn.x, kColumn.y, kColumn.z};
  e.pixelSpacing = {1.5, 2.0};
  e.sliceThickness = kGap;
  const int order[kPositions] = {3, 0, 5, 1, 4, 2};
  for (const int z : order)
    for (const int t : steps) {
      voxwall::test::EnhancedFrame f;
      f.position = kOrigin + double(z) * kGap * kNormal;
      f.stackPosition = std::uint32_t(z + 1);
      if (temporalIndex) f.temporalIndex = std::uint32_t(t + 1);
      f.intercept = -100;  // value = stored - 100
      for (int y = 0; y < kRows; ++y)
        for (int x = 0; x < kCols; ++x)
          f.pixels.push_back(std::int16_t(runValue(x, y, z, t) + 100));
      e.frames.push_back(std::move(f));
    }
  return e;
}

}  // namespace

// One enhanced file of two time points (Temporal Position Index in each frame's content).
TEST(DicomSeries, AnEnhancedFileOfTwoTimePointsIsATimeSeries) {
  TempDir dir;
  voxwall::test::writeEnhancedDicom(dir.path("cine.dcm"), enhancedRun({0, 1}, true));
  const DicomInput input(dir.path("cine.dcm"), {});
  ASSERT_EQ(input.steps(), 2);
  EXPECT_EQ(input.describeSteps(), "2 time steps of 6 slices, ordered by temporal position");
  for (int t = 0; t < 2; ++t) expectStep(input.read(t), t);
}

// A folder of enhanced files, one per time point, ordered by their instance numbers.
TEST(DicomSeries, AFolderOfEnhancedFilesOnePerTimePointIsATimeSeries) {
  TempDir dir;
  std::filesystem::create_directories(dir.path("run"));
  for (const int t : {2, 0, 1}) {
    auto e = enhancedRun({t}, false);
    e.instance = t + 1;
    voxwall::test::writeEnhancedDicom(dir.path("run/T" + std::to_string(7 * t % 5) + ".dcm"), e);
  }
  const DicomInput input(dir.path("run"), {});
  ASSERT_EQ(input.steps(), 3);
  EXPECT_EQ(input.describeSteps(), "3 time steps of 6 slices, ordered by instance number");
  for (int t = 0; t < 3; ++t) expectStep(input.read(t), t);
}

// What tells images apart is the files' text: the list stays one printable line.
TEST(DicomSeries, AnImageListFromTheFilesIsOnePrintableLine) {
  TempDir dir;
  auto run = runSlices(2);
  for (RunSlice& r : run) r.slice.imageType = r.t ? "DERIVED\nsink: forged" : "ORIGINAL";
  writeRun(dir, "types", run);
  expectFormatError([&] { readVolume(dir.path("types")); }, dir.path("types"),
                    "(1: image type ORIGINAL (6 files); 2: image type DERIVED?sink: forged (6 "
                    "files))");
}
