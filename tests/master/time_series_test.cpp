// Time series as a user meets them: a 4D NIfTI, a file pattern, a list of files and a raw file of
// several volumes compress into one .vwz; `info` lists the steps, `decompress --step` gives each
// back; steps that disagree and corrupt step sections are refused in one line naming the step.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/image.hpp>

#include "support/cli_run.hpp"
#include "support/dicom_writer.hpp"
#include "support/image_expect.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;

namespace {

constexpr int kSize = 24, kSteps = 4;

codec::Volume blobs(int step) { return codec::generateOrbitingBlobs(kSize, step, kSteps); }

// Every step of `vwz`, written by `decompress --step k`, equals `want(k)` voxel for voxel.
template <class Want>
void expectStepsDecompressTo(const std::string& vwz, int steps, const test::TempDir& dir,
                             Want&& want) {
  for (int k = 0; k < steps; ++k) {
    const std::string out = dir.path("step" + std::to_string(k) + ".nrrd");
    const CliRun r =
        runVoxwall("decompress " + vwz + " -o " + out + " --step " + std::to_string(k));
    ASSERT_EQ(r.status, 0) << r.out;
    const codec::Volume back = codec::readVolume(out);
    const codec::Volume expected = want(k);
    EXPECT_EQ(back.dims, expected.dims) << "step " << k;
    EXPECT_EQ(back.type, expected.type) << "step " << k;
    EXPECT_TRUE(back.data == expected.data) << vwz << " step " << k;
  }
}

// `generate blobs` of kSteps steps of kSize^3, compressed with vq: the .vwz's path.
std::string compressedBlobs(const test::TempDir& dir) {
  const std::string nii = dir.path("b.nii"), vwz = dir.path("b.vwz");
  const CliRun g = runVoxwall("generate blobs --steps 4 --size 24 -o " + nii);
  EXPECT_EQ(g.status, 0) << g.out;
  const CliRun c = runVoxwall("compress -q " + nii + " -o " + vwz + " --codec vq");
  EXPECT_EQ(c.status, 0) << c.out;
  return vwz;
}

}  // namespace

TEST(TimeSeries, A4dNiftiRoundTripsLosslesslyThroughRawAndVqStepByStep) {
  test::TempDir dir;
  const CliRun g = runVoxwall("generate blobs --steps 4 --size 24 -o " + dir.path("blobs.nii.gz"));
  ASSERT_EQ(g.status, 0) << g.out;
  EXPECT_EQ(codec::niftiStepCount(dir.path("blobs.nii.gz")), kSteps);
  for (const char* c : {"raw", "vq"}) {
    const std::string vwz = dir.path(std::string(c) + ".vwz");
    const CliRun r =
        runVoxwall("compress -q " + dir.path("blobs.nii.gz") + " -o " + vwz + " --codec " + c);
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find("4 steps of 24x24x24 uint8"), std::string::npos) << r.out;
    const auto file = codec::ContainerFile::open(vwz);
    EXPECT_EQ(file.stepCount(), kSteps);
    EXPECT_EQ(file.version(), codec::kContainerVersion);
    expectStepsDecompressTo(vwz, kSteps, dir, blobs);
    // info lists every step, with its own range.
    const CliRun info = runVoxwall("info " + vwz);
    ASSERT_EQ(info.status, 0) << info.out;
    EXPECT_NE(info.out.find("4 steps"), std::string::npos) << info.out;
    for (int k = 0; k < kSteps; ++k) {
      const codec::Volume v = blobs(k);
      char line[96];
      std::snprintf(line, sizeof line, "values %g .. %g, lossless", v.valueMin, v.valueMax);
      EXPECT_NE(info.out.find("step " + std::to_string(k)), std::string::npos) << info.out;
      EXPECT_NE(info.out.find(line), std::string::npos) << line << "\n" << info.out;
    }
  }
  // A series needs --step to decompress; a step past the end is refused.
  expectOneLineError(runVoxwall("decompress " + dir.path("vq.vwz") + " -o " + dir.path("x.nrrd")),
                     "voxwall: " + dir.path("vq.vwz") + " holds 4 steps: give --step K");
  expectOneLineError(
      runVoxwall("decompress " + dir.path("vq.vwz") + " -o " + dir.path("x.nrrd") + " --step 4"),
      "voxwall: --step 4: ");
}

// The 4D NIfTI of nibabel's test data (python3-nibabel): two int16 steps of an fMRI run.
TEST(TimeSeries, ARealFmriSeriesRoundTripsLosslessly) {
  const std::string fmri = "/usr/lib/python3/dist-packages/nibabel/tests/data/example4d.nii.gz";
  if (!std::filesystem::exists(fmri)) GTEST_SKIP() << fmri << " missing (python3-nibabel)";
  test::TempDir dir;
  const std::string vwz = dir.path("fmri.vwz");
  const CliRun r = runVoxwall("compress -q " + fmri + " -o " + vwz + " --codec vq");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("2 steps of 128x96x24 int16"), std::string::npos) << r.out;
  expectStepsDecompressTo(vwz, 2, dir, [&](int k) { return codec::readNiftiStep(fmri, k); });
  EXPECT_FALSE(codec::readNiftiStep(fmri, 0).data == codec::readNiftiStep(fmri, 1).data);
}

// A DICOM fMRI export (2 positions x 3 volumes, ordered only by their instance numbers): `info`
// tells its steps, `compress` makes one .vwz of them, each step decompresses to the DICOM read of
// that step; a single volume of it is refused in one line. Echoes are listed as images.
TEST(TimeSeries, ADicomFmriFolderCompressesIntoOneFileAndEchoesAreListedAsImages) {
  test::TempDir dir;
  std::filesystem::create_directories(dir.path("fmri"));
  for (int k = 0; k < 6; ++k) {
    test::DicomSlice s;
    s.modality = "MR", s.columns = 8, s.rows = 6;
    for (int i = 0; i < 48; ++i) s.pixels.push_back(std::int16_t(i + 100 * k));
    s.position = {0, 0, 3.0 * (k % 2)};
    s.instance = k + 1;
    test::writeDicom(dir.path("fmri/IM" + std::to_string(5 - k)), s);
  }
  const CliRun info = runVoxwall("info " + dir.path("fmri"));
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("steps       3 time steps of 2 slices, ordered by instance number"),
            std::string::npos)
      << info.out;
  const std::string vwz = dir.path("fmri.vwz");
  const CliRun r = runVoxwall("compress -q " + dir.path("fmri") + " -o " + vwz + " --codec raw");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("3 steps of 8x6x2 int16"), std::string::npos) << r.out;
  const codec::DicomInput input(dir.path("fmri"), {});
  expectStepsDecompressTo(vwz, 3, dir, [&](int k) { return input.read(k); });
  EXPECT_EQ(input.read(2).valueAt(0), 400);  // step 2, position 0: instance 5
  expectOneLineError(runVoxwall("render " + dir.path("fmri") + " --out " + dir.path("x.png")),
                     "voxwall: " + dir.path("fmri") + ": holds 3 time steps of 2 slices");
  // The same slices as three echoes: images, listed by `info`, never time steps.
  std::filesystem::create_directories(dir.path("echoes"));
  for (int k = 0; k < 6; ++k) {
    test::DicomSlice s;
    s.modality = "MR", s.columns = 8, s.rows = 6, s.pixels.assign(48, std::int16_t(k));
    s.position = {0, 0, 3.0 * (k % 2)};
    s.instance = k + 1, s.echoNumber = k / 2 + 1;
    test::writeDicom(dir.path("echoes/IM" + std::to_string(k)), s);
  }
  const CliRun images = runVoxwall("info " + dir.path("echoes"));
  ASSERT_EQ(images.status, 0) << images.out;
  EXPECT_NE(images.out.find("images      3 (read one with --dicom-image N)\n  1: echo 1, 2 "
                            "slices\n  2: echo 2, 2 slices\n  3: echo 3, 2 slices\n"),
            std::string::npos)
      << images.out;
  const CliRun third = runVoxwall("info " + dir.path("echoes") + " --dicom-image 3");
  ASSERT_EQ(third.status, 0) << third.out;
  EXPECT_NE(third.out.find("values      4 .. 5"), std::string::npos) << third.out;
}

TEST(TimeSeries, AFilePatternAndAFileListCompressInNumberOrder) {
  test::TempDir dir;
  // Numbers 8, 9, 10 printed by %d: number order is not the names' order.
  for (int k = 0; k < 3; ++k)
    codec::writeVolume(blobs(k), dir.path("sim_" + std::to_string(k + 8) + ".nrrd"));
  const CliRun r = runVoxwall("compress -q '" + dir.path("sim_%d.nrrd") + "' -o " +
                              dir.path("p.vwz") + " --codec vq");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("3 steps"), std::string::npos) << r.out;
  expectStepsDecompressTo(dir.path("p.vwz"), 3, dir, blobs);

  const CliRun list = runVoxwall("compress -q -o " + dir.path("l.vwz") + " --time-files " +
                                 dir.path("sim_10.nrrd") + " " + dir.path("sim_8.nrrd"));
  ASSERT_EQ(list.status, 0) << list.out;
  expectStepsDecompressTo(dir.path("l.vwz"), 2, dir, [](int k) { return blobs(k == 0 ? 2 : 0); });

  expectOneLineError(
      runVoxwall("compress -q '" + dir.path("none_%04d.nrrd") + "' -o " + dir.path("n.vwz")),
      "voxwall: " + dir.path("none_%04d.nrrd") + ": no file in ");
}

TEST(TimeSeries, ARawFileOfSeveralVolumesCompressesWithTime) {
  test::TempDir dir;
  {
    std::ofstream out(dir.path("three.raw"), std::ios::binary);
    for (int k = 0; k < 3; ++k) {
      const codec::Volume v = blobs(k);
      out.write(reinterpret_cast<const char*>(v.data.data()), std::streamsize(v.data.size()));
    }
  }
  const std::string layout = " --dims 24,24,24 --type uint8";
  const CliRun r = runVoxwall("compress -q " + dir.path("three.raw") + layout + " --time 3 -o " +
                              dir.path("r.vwz") + " --codec vq");
  ASSERT_EQ(r.status, 0) << r.out;
  expectStepsDecompressTo(dir.path("r.vwz"), 3, dir, blobs);
  // Four volumes do not fit in the file.
  const CliRun four = runVoxwall("compress -q " + dir.path("three.raw") + layout + " --time 4 -o " +
                                 dir.path("r4.vwz"));
  expectOneLineError(four, "voxwall: " + dir.path("three.raw") + ": truncated");
}

// The first step that differs from step 0 in size, type or spacing is named, in one line.
TEST(TimeSeries, StepsThatDisagreeAreRefusedNamingTheFirst) {
  test::TempDir dir;
  codec::writeVolume(blobs(0), dir.path("a.nrrd"));
  codec::writeVolume(blobs(1), dir.path("b.nrrd"));
  codec::writeVolume(codec::generateOrbitingBlobs(20, 2, kSteps), dir.path("c.nrrd"));
  const CliRun r =
      runVoxwall("compress -q -o " + dir.path("x.vwz") + " --time-files " + dir.path("a.nrrd") +
                 " " + dir.path("b.nrrd") + " " + dir.path("c.nrrd"));
  expectOneLineError(r, "voxwall: " + dir.path("c.nrrd") + ": step 2 (c.nrrd) is 20x20x20 uint8");
  EXPECT_NE(r.out.find("but step 0 (a.nrrd) is 24x24x24 uint8"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.path("x.vwz")));
}

// A flipped byte in one step's section: every command that reads the file refuses it in one line
// naming that step.
TEST(TimeSeries, ACorruptStepSectionIsRefusedNamingTheStep) {
  test::TempDir dir;
  const std::string vwz = compressedBlobs(dir);
  ASSERT_FALSE(::testing::Test::HasFailure());
  std::string bytes = test::readFile(vwz);
  // The first table entry of step 2.
  std::uint32_t sections = 0;
  std::memcpy(&sections, bytes.data() + 36, 4);
  std::uint64_t offset = 0;
  for (std::uint32_t i = 0; i < sections && !offset; ++i) {
    std::uint32_t step = 0;
    std::memcpy(&step, bytes.data() + 128 + 32 * i + 4, 4);
    if (step == 2) std::memcpy(&offset, bytes.data() + 128 + 32 * i + 8, 8);
  }
  ASSERT_GT(offset, 0u);
  bytes[offset + 5] ^= 0x10;
  test::writeFile(vwz, bytes);
  for (const std::string& command :
       {"info " + vwz, "decompress " + vwz + " --step 0 -o " + dir.path("o.nrrd"),
        "render " + vwz + " --size 32x32 --out " + dir.path("frames")}) {
    const CliRun r = runVoxwall(command);
    expectOneLineError(r, "voxwall: " + vwz + ": section ");
    EXPECT_NE(r.out.find("step 2): checksum mismatch"), std::string::npos) << command << r.out;
  }
}

// `render --time 0:3` writes four frames, each the picture a render of that step alone gives
// (the camera still; --range per-step places the map on each step's values as a lone step's
// render does). With the series' range (the default) the frames differ from those renders, as
// they must where a step's values span less than the series'. The step along the ray is fixed:
// the error budget picks it on the job's first step, a lone step's render on its own.
TEST(TimeSeries, RenderTimeWritesAFrameAStepEqualToSingleStepRenders) {
  test::TempDir dir;
  const std::string vwz = compressedBlobs(dir);
  ASSERT_FALSE(::testing::Test::HasFailure());
  const std::string view = " --size 64x48 --path still --shading --step 0.5 -q";
  const CliRun series =
      runVoxwall("render " + vwz + view + " --time 0:3 --range per-step --out " + dir.path("t"));
  ASSERT_EQ(series.status, 0) << series.out;
  const CliRun whole = runVoxwall("render " + vwz + view + " --time 0:3 --out " + dir.path("w"));
  ASSERT_EQ(whole.status, 0) << whole.out;
  EXPECT_FALSE(std::filesystem::exists(dir.path("t/frame_00004.png")));
  int differ = 0;
  for (int k = 0; k < kSteps; ++k) {
    const std::string step = dir.path("s" + std::to_string(k) + ".vwz");
    ASSERT_EQ(runVoxwall("decompress " + vwz + " --step " + std::to_string(k) + " -o " +
                         dir.path("s.nrrd"))
                  .status,
              0);
    ASSERT_EQ(
        runVoxwall("compress -q " + dir.path("s.nrrd") + " -o " + step + " --codec vq").status, 0);
    const std::string out = dir.path("single" + std::to_string(k));
    const CliRun one = runVoxwall("render " + step + view + " --out " + out);
    ASSERT_EQ(one.status, 0) << one.out;
    char name[32];
    std::snprintf(name, sizeof name, "/frame_%05d.png", k);
    const Image alone = readImage(out + "/frame_00000.png");
    test::expectImagesNear(alone, readImage(dir.path("t") + name), 0, 0,
                           "step " + std::to_string(k));
    differ += !(alone.pixels == readImage(dir.path("w") + name).pixels);
  }
  EXPECT_GT(differ, 0) << "the series' range made no frame differ from its lone step's";
  // Every step shows something else: the blobs move.
  EXPECT_FALSE(readImage(dir.path("t/frame_00000.png")).pixels ==
               readImage(dir.path("t/frame_00002.png")).pixels);
}

TEST(TimeSeries, RenderRefusesStepsTheVolumeDoesNotHave) {
  test::TempDir dir;
  ASSERT_EQ(runVoxwall("generate blobs --steps 3 --size 16 -o " + dir.path("b.vwz")).status, 0);
  expectOneLineError(
      runVoxwall("render " + dir.path("b.vwz") + " --size 32x32 --time 1:5 --out " + dir.path("f")),
      "voxwall: --time 1:5: the volume has 3 step(s), 0 to 2");
  expectOneLineError(
      runVoxwall("render " + dir.path("b.vwz") + " --size 32x32 --time 2:1 --out " + dir.path("f")),
      "voxwall: --time: the last step comes before the first");
  expectOneLineError(runVoxwall("render " + dir.path("b.vwz") +
                                " --size 32x32 --time-rate 2 "
                                "--out " +
                                dir.path("f")),
                     "voxwall: --time-rate plays a series on the wall (--sink)");
}

// ksvd codes a series with one dictionary learned on blocks of several steps: stored once, it
// makes the file smaller than a dictionary a step (--steps-alone) at no loss of PSNR over the
// steps. A step alone may come out a little closer with its own dictionary (step 4 here: 37.97
// against 38.74 dB in a release build, 37.67 with the sanitizers' floating point), so each step
// is held to a floor, and their mean to the mean of a dictionary a step (40.4 against 38.9 dB).
TEST(TimeSeries, KsvdSharesOneDictionaryAcrossTheSteps) {
  test::TempDir dir;
  ASSERT_EQ(runVoxwall("generate blobs --steps 6 --size 32 -o " + dir.path("b.nii")).status, 0);
  const std::string shared = dir.path("shared.vwz"), alone = dir.path("alone.vwz");
  const std::string common = " --codec ksvd --tolerance 0.01 --levels 1 -q";
  const CliRun s = runVoxwall("compress " + dir.path("b.nii") + " -o " + shared + common);
  ASSERT_EQ(s.status, 0) << s.out;
  EXPECT_NE(s.out.find("one dictionary of"), std::string::npos) << s.out;
  const CliRun a =
      runVoxwall("compress " + dir.path("b.nii") + " -o " + alone + common + " --steps-alone");
  ASSERT_EQ(a.status, 0) << a.out;
  const auto sharedFile = codec::ContainerFile::open(shared);
  const auto aloneFile = codec::ContainerFile::open(alone);
  EXPECT_GT(sharedFile.sharedBytes(), 0u);
  EXPECT_EQ(aloneFile.sharedBytes(), 0u);
  EXPECT_LT(sharedFile.fileBytes(), aloneFile.fileBytes());
  const codec::Codec& ksvd = codec::codecOf(sharedFile.info(), shared);
  double sharedSum = 0, ownSum = 0;
  for (int k = 0; k < 6; ++k) {
    const codec::Volume want = codec::generateOrbitingBlobs(32, k, 6);
    const double withShared =
        codec::psnr(want, ksvd.decode(sharedFile.stepInfo(k), sharedFile.stepSections(k)));
    const double withOwn =
        codec::psnr(want, ksvd.decode(aloneFile.stepInfo(k), aloneFile.stepSections(k)));
    EXPECT_GT(withShared, withOwn - 2.0) << "step " << k;
    EXPECT_GT(withShared, 35.0) << "step " << k;
    sharedSum += withShared, ownSum += withOwn;
  }
  EXPECT_GE(sharedSum, ownSum);
}

// vq codes a series with one codebook (the unique bricks of every step), stored once. Lossless,
// it keeps it where it is smaller than a codebook a step: steps that repeat bricks (here two
// volumes, each twice, at a size that is not whole bricks, so each step is padded alone) come
// back exactly from a smaller file; moving blobs, which repeat no brick, keep a codebook a step.
// Reduced, one codebook is kept, and info says each step's own PSNR.
TEST(TimeSeries, VqSharesOneCodebookAcrossTheSteps) {
  test::TempDir dir;
  constexpr int kSide = 30, kN = 5;
  const std::string a = dir.path("a.nrrd"), b = dir.path("b.nrrd");
  ASSERT_EQ(runVoxwall("generate marschner-lobb --size 30 -o " + a).status, 0);
  ASSERT_EQ(runVoxwall("generate blobs --size 30 -o " + b).status, 0);
  const std::string files = " --time-files " + a + " " + b + " " + a + " " + b;
  const std::string shared = dir.path("shared.vwz"), alone = dir.path("alone.vwz");
  const CliRun s = runVoxwall("compress" + files + " -o " + shared + " --codec vq");
  ASSERT_EQ(s.status, 0) << s.out;
  EXPECT_NE(s.out.find("one codebook of"), std::string::npos) << s.out;
  EXPECT_EQ(s.out.find("a codebook a step:"), std::string::npos) << s.out;
  const CliRun r = runVoxwall("compress -q" + files + " -o " + alone + " --codec vq --steps-alone");
  ASSERT_EQ(r.status, 0) << r.out;
  const auto sharedFile = codec::ContainerFile::open(shared);
  const auto aloneFile = codec::ContainerFile::open(alone);
  EXPECT_GT(sharedFile.sharedBytes(), 0u);
  EXPECT_LT(sharedFile.fileBytes(), aloneFile.fileBytes());
  expectStepsDecompressTo(shared, 4, dir, [&](int k) { return codec::readVolume(k % 2 ? b : a); });
  const CliRun info = runVoxwall("info " + shared);
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("one for every step"), std::string::npos) << info.out;

  ASSERT_EQ(runVoxwall("generate blobs --steps 5 --size 30 -o " + dir.path("m.nii")).status, 0);
  const auto want = [](int k) { return codec::generateOrbitingBlobs(kSide, k, kN); };
  const std::string moving = dir.path("moving.vwz"), movingAlone = dir.path("moving-alone.vwz");
  const CliRun m = runVoxwall("compress -q " + dir.path("m.nii") + " -o " + moving + " --codec vq");
  ASSERT_EQ(m.status, 0) << m.out;
  ASSERT_EQ(runVoxwall("compress -q " + dir.path("m.nii") + " -o " + movingAlone +
                       " --codec vq --steps-alone")
                .status,
            0);
  EXPECT_LE(codec::ContainerFile::open(moving).fileBytes(),
            codec::ContainerFile::open(movingAlone).fileBytes());
  expectStepsDecompressTo(moving, kN, dir, want);

  const std::string lossy = dir.path("lossy.vwz");
  const CliRun l =
      runVoxwall("compress -q " + dir.path("m.nii") + " -o " + lossy + " --codec vq --reduction 8");
  ASSERT_EQ(l.status, 0) << l.out;
  const auto lossyFile = codec::ContainerFile::open(lossy);
  EXPECT_GT(lossyFile.sharedBytes(), 0u);
  const codec::Codec& vq = codec::codecOf(lossyFile.info(), lossy);
  const CliRun lossyInfo = runVoxwall("info " + lossy);
  ASSERT_EQ(lossyInfo.status, 0) << lossyInfo.out;
  for (int k = 0; k < kN; ++k) {
    const double got =
        codec::psnr(want(k), vq.decode(lossyFile.stepInfo(k), lossyFile.stepSections(k)));
    EXPECT_GT(got, 30.0) << "step " << k;
    EXPECT_LT(got, 200.0) << "step " << k << " is lossless at --reduction 8";
    // info says each step's own PSNR, as measured here (to its two decimals).
    char said[48];
    std::snprintf(said, sizeof said, "PSNR %.2f dB", got);
    EXPECT_NE(lossyInfo.out.find(said), std::string::npos) << said << "\n" << lossyInfo.out;
  }
}

// A 4D NRRD (its fourth, slowest axis of kind time) is a series: raw encoding is read a step at
// a time from the file, ASCII through teem; both round-trip losslessly through vq. A fourth axis
// that says it is space is refused in one line, and a series is refused where one volume is
// needed, naming its steps.
TEST(TimeSeries, A4dNrrdIsASeriesAlongItsTimeAxis) {
  test::TempDir dir;
  constexpr int kSide = 12, kN = 3;
  const auto want = [](int k) { return codec::generateOrbitingBlobs(kSide, k, kN); };
  auto write = [&](const std::string& name, const std::string& kinds, bool ascii) {
    std::string text = "NRRD0004\ntype: uint8\ndimension: 4\nsizes: 12 12 12 3\nkinds: " + kinds +
                       "\nencoding: " + (ascii ? "ascii" : "raw") + "\n\n";
    for (int k = 0; k < kN; ++k) {
      const codec::Volume v = want(k);
      if (ascii) {
        for (const std::byte b : v.data) text += std::to_string(int(b)) + "\n";
      } else {
        text.append(reinterpret_cast<const char*>(v.data.data()), v.data.size());
      }
    }
    test::writeFile(dir.path(name), text);
    return dir.path(name);
  };
  for (const bool ascii : {false, true}) {
    const std::string nrrd =
        write(ascii ? "ascii.nrrd" : "raw.nrrd", "domain domain domain time", ascii);
    EXPECT_EQ(codec::nrrdStepCount(nrrd), kN);
    const std::string vwz = dir.path(ascii ? "ascii.vwz" : "raw.vwz");
    const CliRun r = runVoxwall("compress -q " + nrrd + " -o " + vwz + " --codec vq");
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find("3 steps of 12x12x12 uint8"), std::string::npos) << r.out;
    expectStepsDecompressTo(vwz, kN, dir, want);
    const CliRun info = runVoxwall("info " + nrrd);
    ASSERT_EQ(info.status, 0) << info.out;
    EXPECT_NE(info.out.find("steps       3"), std::string::npos) << info.out;
  }
  expectOneLineError(runVoxwall("render " + dir.path("raw.nrrd") + " --no-write"),
                     "voxwall: " + dir.path("raw.nrrd") + ": holds 3 time steps");
  const std::string space = write("space.nrrd", "domain domain domain domain", false);
  expectOneLineError(runVoxwall("compress -q " + space + " -o " + dir.path("s.vwz")),
                     "voxwall: " + space + ": has 4 axes");
}
