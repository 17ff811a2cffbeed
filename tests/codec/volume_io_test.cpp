#include <gtest/gtest.h>
#include <nifti1_io.h>
#include <sys/resource.h>
#include <teem/nrrd.h>

#include <csignal>
#include <cstring>
#include <filesystem>
#include <limits>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>

#include "support/format_error_expect.hpp"
#include "support/patterned_volume.hpp"
#include "support/temp_dir.hpp"
#include "support/volume_expect.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::expectSameVoxels;
using voxwall::test::TempDir;

namespace {

using voxwall::test::patterned;

using voxwall::test::expectFormatError;

const ScalarType kTypes[] = {ScalarType::UInt8, ScalarType::UInt16, ScalarType::Int16,
                             ScalarType::Float32};

}  // namespace

TEST(VolumeIo, RawRoundTripsEveryType) {
  TempDir dir;
  for (auto type : kTypes) {
    const Volume v = patterned(type);
    const auto path = dir.path(std::string(scalarName(type)) + ".raw");
    writeVolume(v, path);
    RawLayout layout{v.dims, type, v.spacing};
    const Volume back = readVolume(path, layout);
    expectSameVoxels(v, back);
    EXPECT_EQ(back.spacing, v.spacing);
  }
}

TEST(VolumeIo, RawReadsBigEndianAndSkipsHeader) {
  TempDir dir;
  std::string bytes = "HDR!";
  for (int i = 0; i < 8; ++i) bytes += {char(0x12), char(i)};
  test::writeFile(dir.path("be.raw"), bytes);
  RawLayout layout{{2, 2, 2}, ScalarType::UInt16};
  layout.bigEndian = true;
  layout.headerBytes = 4;
  const Volume v = readRaw(dir.path("be.raw"), layout);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(v.as<std::uint16_t>()[std::size_t(i)], 0x1200 + i);
}

TEST(VolumeIo, RawRejectsTruncatedAndOversizedFiles) {
  TempDir dir;
  const Volume v = patterned(ScalarType::UInt16);
  writeVolume(v, dir.path("v.raw"));
  std::string bytes = test::readFile(dir.path("v.raw"));
  test::writeFile(dir.path("short.raw"), bytes.substr(0, bytes.size() - 1));
  test::writeFile(dir.path("long.raw"), bytes + "x");
  RawLayout layout{v.dims, v.type};
  expectFormatError([&] { readRaw(dir.path("short.raw"), layout); }, dir.path("short.raw"),
                    "truncated");
  expectFormatError([&] { readRaw(dir.path("long.raw"), layout); }, dir.path("long.raw"),
                    "--header-bytes");
  expectFormatError([&] { readVolume(dir.path("v.raw")); }, dir.path("v.raw"), "--dims");
}

TEST(VolumeIo, NrrdRoundTripsEveryTypeAttachedAndDetached) {
  TempDir dir;
  for (auto type : kTypes)
    for (const char* ext : {".nrrd", ".nhdr"}) {
      const Volume v = patterned(type);
      const auto path = dir.path(std::string(scalarName(type)) + ext);
      writeVolume(v, path);
      const Volume back = readVolume(path);
      expectSameVoxels(v, back);
      EXPECT_DOUBLE_EQ(back.spacing.x, 0.5);
      EXPECT_DOUBLE_EQ(back.spacing.z, 1.25);
    }
}

TEST(VolumeIo, NiftiRoundTripsEveryTypePlainAndGzipped) {
  TempDir dir;
  for (auto type : kTypes)
    for (const char* ext : {".nii", ".nii.gz"}) {
      const Volume v = patterned(type);
      const auto path = dir.path(std::string(scalarName(type)) + ext);
      writeVolume(v, path);
      const Volume back = readVolume(path);
      expectSameVoxels(v, back);
      EXPECT_NEAR(back.spacing.y, 0.75, 1e-6);
    }
}

TEST(VolumeIo, TruncatedFilesAreRefusedWithOneLine) {
  TempDir dir;
  const Volume v = patterned(ScalarType::UInt16, {32, 32, 16});
  for (const char* name : {"v.nrrd", "v.nii", "v.nii.gz"}) {
    const auto path = dir.path(name);
    writeVolume(v, path);
    const std::string bytes = test::readFile(path);
    for (double keep : {0.1, 0.5, 0.95}) {
      const auto cut = dir.path(std::string("cut-") + name);
      test::writeFile(cut, bytes.substr(0, std::size_t(double(bytes.size()) * keep)));
      expectFormatError([&] { readVolume(cut); }, cut);
    }
  }
}

TEST(VolumeIo, GarbageAndUnknownFilesAreRefused) {
  TempDir dir;
  test::writeFile(dir.path("junk.nii"), std::string(400, 'x'));
  test::writeFile(
      dir.path("junk.nrrd"),
      "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 100000\nencoding: raw\n\nabc");
  test::writeFile(dir.path("junk.xyz"), "hello");
  expectFormatError([&] { readVolume(dir.path("junk.nii")); }, dir.path("junk.nii"));
  expectFormatError([&] { readVolume(dir.path("junk.nrrd")); }, dir.path("junk.nrrd"),
                    "over the limit");
  expectFormatError([&] { readVolume(dir.path("junk.xyz")); }, dir.path("junk.xyz"),
                    "unknown volume format");
  expectFormatError([&] { readVolume(dir.path("missing.nii")); }, dir.path("missing.nii"));
}

TEST(VolumeIo, NrrdHeaderAskingForMoreThanTheFileHoldsIsRefusedBeforeAllocating) {
  TempDir dir;
  // 2^30 voxels claimed, 3 bytes present, raw encoding.
  test::writeFile(
      dir.path("big.nrrd"),
      "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1024 1024 1024\nencoding: raw\n\nabc");
  expectFormatError([&] { readVolume(dir.path("big.nrrd")); }, dir.path("big.nrrd"), "truncated");
}

TEST(VolumeIo, DefaultMriTemplateReadsWhenInstalled) {
  const std::string path = "/usr/share/mricron/templates/ch2better.nii.gz";
  if (!std::filesystem::exists(path))
    GTEST_SKIP() << path << " not installed (Debian mricron-data)";
  const Volume v = readVolume(path);
  EXPECT_EQ(v.dims, glm::ivec3(301, 370, 316));
  EXPECT_EQ(v.type, ScalarType::UInt8);
  EXPECT_NEAR(v.spacing.x, 0.5, 1e-6);
  EXPECT_EQ(v.valueMin, 0);
  EXPECT_GT(v.valueMax, 100);
}

namespace {
// Writes a NIfTI-1 file with nifticlib directly, to reach header fields writeVolume never sets.
void writeNiftiWith(const std::string& path, int dims4, float slope, float inter) {
  int dims[8] = {dims4 > 1 ? 4 : 3, 3, 2, 2, dims4, 1, 1, 1};
  nifti_image* nim = nifti_make_new_nim(dims, DT_UINT8, 1);
  auto* data = static_cast<std::uint8_t*>(nim->data);
  for (std::size_t i = 0; i < nim->nvox; ++i) data[i] = std::uint8_t(i);
  nim->scl_slope = slope;
  nim->scl_inter = inter;
  nim->nifti_type = NIFTI_FTYPE_NIFTI1_1;
  nifti_set_filenames(nim, path.c_str(), 0, 1);
  nifti_image_write(nim);
  nifti_image_free(nim);
}
}  // namespace

TEST(VolumeIo, NiftiScaleSlopeGivesFloatValues) {
  TempDir dir;
  writeNiftiWith(dir.path("scaled.nii"), 1, 2.0f, -10.0f);
  const Volume v = readVolume(dir.path("scaled.nii"));
  ASSERT_EQ(v.type, ScalarType::Float32);
  for (std::size_t i = 0; i < v.voxelCount(); ++i)
    EXPECT_EQ(v.as<float>()[i], 2.0f * float(i) - 10.0f);
  writeNiftiWith(dir.path("plain.nii"), 1, 1.0f, 0.0f);
  EXPECT_EQ(readVolume(dir.path("plain.nii")).type, ScalarType::UInt8);
}

// A NIfTI time series is not one volume: readVolume says how many steps it holds and what takes
// them; its steps read one at a time.
TEST(VolumeIo, NiftiTimeSeriesIsReadStepByStepNotAsOneVolume) {
  TempDir dir;
  writeNiftiWith(dir.path("4d.nii"), 3, 1.0f, 0.0f);
  expectFormatError([&] { readVolume(dir.path("4d.nii")); }, dir.path("4d.nii"),
                    "holds 3 time steps: `voxwall compress` makes one .vwz of them");
  EXPECT_EQ(niftiStepCount(dir.path("4d.nii")), 3);
  EXPECT_EQ(readNiftiStep(dir.path("4d.nii"), 2).dims, readNiftiStep(dir.path("4d.nii"), 0).dims);
  EXPECT_THROW(readNiftiStep(dir.path("4d.nii"), 3), std::invalid_argument);
}

// Hardening: each of these allocated, crashed or said too little before.

TEST(VolumeIo, RawChecksTheFileSizeBeforeAllocating) {
  TempDir dir;
  test::writeFile(dir.path("small.raw"), std::string(256 * 1024, '\0'));
  RawLayout layout;
  layout.dims = {2048, 2048, 2048};  // 32 GiB of float32: more than the machine could allocate
  layout.type = ScalarType::Float32;
  expectFormatError([&] { readVolume(dir.path("small.raw"), layout); }, dir.path("small.raw"),
                    "truncated");
}

TEST(VolumeIo, CompressedNrrdIsJudgedByWhatItDecodesTo) {
  TempDir dir;
  // A valid all-zero 128^3 volume compresses far beyond 1100:1, the bound once assumed.
  for (const char* encoding : {"bzip2", "gzip"}) {
    const std::string nhdr = dir.path(std::string("z-") + encoding + ".nrrd");
    {  // written by teem itself
      Nrrd* n = nrrdNew();
      std::vector<std::uint8_t> voxels(128 * 128 * 128, 0);
      nrrdWrap_va(n, voxels.data(), nrrdTypeUChar, 3, size_t(128), size_t(128), size_t(128));
      NrrdIoState* io = nrrdIoStateNew();
      io->encoding = std::string(encoding) == "bzip2" ? nrrdEncodingBzip2 : nrrdEncodingGzip;
      ASSERT_EQ(nrrdSave(nhdr.c_str(), n, io), 0);
      nrrdIoStateNix(io);
      nrrdNix(n);
    }
    if (std::string(encoding) == "bzip2") {
      EXPECT_LT(std::filesystem::file_size(nhdr), 128u * 128 * 128 / 1100);
    }
    const Volume v = readVolume(nhdr);
    EXPECT_EQ(v.dims, glm::ivec3(128, 128, 128));
    EXPECT_EQ(v.valueMax, 0);
    // Cut short, it is still refused as truncated, before teem allocates the whole volume.
    const auto bytes = test::readFile(nhdr);
    const std::string cut = dir.path(std::string("cut-") + encoding + ".nrrd");
    test::writeFile(cut, bytes.substr(0, bytes.size() - 20));
    expectFormatError([&] { readVolume(cut); }, cut);
  }
}

TEST(VolumeIo, GarbageNrrdHeadersAreNotEchoedRaw) {
  TempDir dir;
  test::writeFile(dir.path("g.nrrd"), std::string("NRRD0004\ntype: \x1b[31mred\x07\x01 ") +
                                          std::string(500, 'A') + "\n\n");
  try {
    readVolume(dir.path("g.nrrd"));
    FAIL() << "garbage header accepted";
  } catch (const FormatError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\x1b'), std::string::npos) << what;
    EXPECT_EQ(what.find('\x07'), std::string::npos) << what;
    EXPECT_LT(what.size(), 400u) << what;
  }
}

namespace {
// Writes `volume`-less NIfTI-1 headers with one field changed.
void writeNiftiPatched(const std::string& path, float voxOffset, float spacingX) {
  writeNiftiWith(path, 1, 1.0f, 0.0f);
  auto bytes = test::readFile(path);
  std::memcpy(bytes.data() + 108, &voxOffset, 4);  // vox_offset
  std::memcpy(bytes.data() + 80, &spacingX, 4);    // pixdim[1]
  test::writeFile(path, bytes);
}
}  // namespace

TEST(VolumeIo, NiftiOffsetsAndSpacingsMustMakeSense) {
  TempDir dir;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::pair<float, const char*> offsets[] = {{1e12f, "past the end"},
                                                   {-1000.0f, "not a byte offset"},
                                                   {nan, "not a byte offset"},
                                                   {100.0f, "inside the 348-byte header"}};
  for (const auto& [offset, fragment] : offsets) {
    const std::string p = dir.path("off.nii");
    writeNiftiPatched(p, offset, 1.0f);
    expectFormatError([&] { readVolume(p); }, p, fragment);
  }
  for (const float spacing : {nan, -2.0f}) {
    const std::string p = dir.path("sp.nii");
    writeNiftiPatched(p, 352.0f, spacing);
    expectFormatError([&] { readVolume(p); }, p, "pixdim[1]");
  }
  const std::string ok = dir.path("ok.nii");
  writeNiftiPatched(ok, 352.0f, 0.5f);
  EXPECT_EQ(readVolume(ok).spacing.x, 0.5);
}

TEST(VolumeIo, ShortAndUnreadableVwzFilesGetTheirOwnMessages) {
  TempDir dir;
  for (int n = 0; n < 8; ++n) {
    const std::string p = dir.path("short" + std::to_string(n) + ".vwz");
    test::writeFile(p, std::string(std::size_t(n), 'V'));
    EXPECT_TRUE(isContainerFile(p));  // so the container reader, not "unknown format", answers
    expectFormatError([&] { ContainerFile::open(p); }, p, "shorter than");
  }
  const std::string folder = dir.path("folder.vwz");
  std::filesystem::create_directory(folder);
  EXPECT_TRUE(isContainerFile(folder));
  expectFormatError([&] { ContainerFile::open(folder); }, folder, "not a regular file");
}

// writers on a full disk. A file-size limit makes every write past it fail as a full
// disk does (EFBIG instead of ENOSPC), in this process only.
TEST(VolumeIo, WritersOnAFullDiskFailWithOneLineAndLeaveNothingBehind) {
  TempDir dir;
  const Volume v = patterned(ScalarType::Float32, {40, 40, 40});  // 256000 bytes of voxels
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  rlimit tight = old;
  tight.rlim_cur = 16 * 1024;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &tight), 0);
  for (const char* name : {"v.raw", "v.nrrd", "v.nii", "v.nii.gz"}) {
    const std::string p = dir.path(name);
    expectFormatError([&] { writeVolume(v, p); }, p, "cannot write");
    EXPECT_FALSE(std::filesystem::exists(p)) << name;
  }
  ::setrlimit(RLIMIT_FSIZE, &old);
  for (const auto& entry : std::filesystem::directory_iterator(dir.path("")))
    ADD_FAILURE() << "left behind: " << entry.path();
  // With room, the same writes work.
  writeVolume(v, dir.path("v.nii.gz"));
  expectSameVoxels(readVolume(dir.path("v.nii.gz")), v);
}
