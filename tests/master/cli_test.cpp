// The voxwall program as a user meets it: commands, files, and one-line errors.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <initializer_list>
#include <random>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/image.hpp>
#include <voxwall/core/text.hpp>
#include <voxwall/node/page_decode.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/cli_run.hpp"
#include "support/dicom_writer.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;

TEST(Cli, HelpListsEverySubcommand) {
  const CliRun r = runVoxwall("--help");
  EXPECT_EQ(r.status, 0);
  for (const char* sub : {"generate", "compress", "decompress", "info", "render", "sink"})
    EXPECT_NE(r.out.find(sub), std::string::npos) << sub;
  const CliRun render = runVoxwall("render --help");
  for (const char* opt :
       {"--size", "--tf", "--camera", "--frames", "--out", "--backend", "--shading"})
    EXPECT_NE(render.out.find(opt), std::string::npos) << opt;
}

TEST(Cli, GenerateCompressInfoDecompressRoundTrip) {
  test::TempDir dir;
  const auto nrrd = dir.path("ml.nrrd"), vwz = dir.path("ml.vwz");
  ASSERT_EQ(runVoxwall("generate marschner-lobb --size 21 --type uint16 -o " + nrrd).status, 0);
  const CliRun c = runVoxwall("compress " + nrrd + " -o " + vwz + " --brick 4 -q");
  ASSERT_EQ(c.status, 0) << c.out;
  EXPECT_NE(c.out.find("bits/voxel"), std::string::npos);
  EXPECT_NE(c.out.find("peak memory"), std::string::npos) << c.out;
  const CliRun info = runVoxwall("info " + vwz);
  ASSERT_EQ(info.status, 0) << info.out;
  for (const char* field :
       {"codec       raw", "21 x 21 x 21", "uint16", "bits/voxel", "ratio", "checksums ok"})
    EXPECT_NE(info.out.find(field), std::string::npos) << field << "\n" << info.out;
  const auto original = codec::readVolume(nrrd);
  for (const char* ext : {".raw", ".nrrd", ".nii.gz"}) {
    const auto out = dir.path(std::string("back") + ext);
    ASSERT_EQ(runVoxwall("decompress " + vwz + " -o " + out).status, 0) << ext;
    codec::RawLayout layout{original.dims, original.type};
    const auto back =
        std::string(ext) == ".raw" ? codec::readVolume(out, layout) : codec::readVolume(out);
    EXPECT_EQ(back.data, original.data) << ext;
  }
  // -q, as every other command takes it: the file and nothing printed.
  const CliRun quiet = runVoxwall("decompress -q " + vwz + " -o " + dir.path("quiet.nrrd"));
  ASSERT_EQ(quiet.status, 0) << quiet.out;
  EXPECT_EQ(quiet.out, "");
  EXPECT_TRUE(std::filesystem::exists(dir.path("quiet.nrrd")));
  // generate too; without -q it says what it wrote.
  const CliRun said = runVoxwall("generate menger --level 2 -o " + dir.path("said.nrrd"));
  ASSERT_EQ(said.status, 0) << said.out;
  EXPECT_NE(said.out.find("9x9x9"), std::string::npos) << said.out;
  const CliRun generated = runVoxwall("generate menger --level 2 -q -o " + dir.path("q.nrrd"));
  ASSERT_EQ(generated.status, 0) << generated.out;
  EXPECT_EQ(generated.out, "");
  EXPECT_TRUE(std::filesystem::exists(dir.path("q.nrrd")));
}

TEST(Cli, CompressReadsRawInputWithItsLayout) {
  test::TempDir dir;
  test::writeFile(dir.path("v.raw"), std::string(4 * 3 * 2 * 2, '\x01'));
  const CliRun ok = runVoxwall("compress " + dir.path("v.raw") +
                               " --dims 4,3,2 --type uint16 -q -o " + dir.path("v.vwz"));
  EXPECT_EQ(ok.status, 0) << ok.out;
  expectOneLineError(runVoxwall("compress " + dir.path("v.raw") +
                                " --dims 4,3,3 --type uint16 -o " + dir.path("w.vwz")),
                     "voxwall: " + dir.path("v.raw") + ": truncated");
}

// Noise does not compress: every codec's default (or lossless) file of 64^3 random voxels is at
// most the voxels plus the allowance for its parameters and the container's header and table, or
// `compress` refuses it with one line, names zfp's lossless mode and writes nothing. svmm and vq
// lossless are refused (they would write 3-9% more than the voxels); --allow-larger writes them;
// zfp --lossless stores the bricks as they are.
TEST(Cli, NoCodecWritesAFileLargerThanTheVoxelsOfNoise) {
  test::TempDir dir;
  std::mt19937 random(7);
  for (const auto& [type, bytes] : {std::pair{"uint8", 1}, std::pair{"int16", 2}}) {
    std::string voxels(std::size_t(64 * 64 * 64 * bytes), '\0');
    for (char& v : voxels) v = char(random());
    const std::string input = dir.path(std::string("noise-") + type + ".raw");
    test::writeFile(input, voxels);
    const std::string from = "compress " + input + " --dims 64,64,64 --type " + type + " -q ";
    for (const codec::Codec* c : codec::codecs()) {
      if (!c->compresses()) continue;
      const std::string name(c->name()), out = dir.path(name + "-" + type + ".vwz");
      const CliRun r = runVoxwall(from + "--codec " + name + " -o " + out);
      SCOPED_TRACE(name + " " + type + ": " + r.out);
      if (r.status == 0) {
        const auto size = std::filesystem::file_size(out);
        EXPECT_LE(size, voxels.size() + voxels.size() / 256 + 4096 + 4096);
      } else {
        expectOneLineError(r, "voxwall: codec " + name + " takes ");
        EXPECT_NE(r.out.find("more than its " + std::to_string(8 * bytes) + "-bit voxels"),
                  std::string::npos);
        EXPECT_NE(r.out.find("--codec zfp --lossless"), std::string::npos);
        EXPECT_FALSE(std::filesystem::exists(out));
      }
      if (name == "svmm" || name == "vq") {
        EXPECT_EQ(r.status, 1);  // lossless by default: noise outgrows the voxels
        const CliRun forced = runVoxwall(from + "--codec " + name + " --allow-larger -o " + out);
        EXPECT_EQ(forced.status, 0) << forced.out;
        EXPECT_GT(std::filesystem::file_size(out), voxels.size());
        const CliRun info = runVoxwall("info " + out);
        EXPECT_NE(info.out.find("the file is larger than its voxels"), std::string::npos)
            << info.out;
      }
    }
    const std::string zfp = dir.path(std::string("zfp-lossless-") + type + ".vwz");
    const CliRun lossless = runVoxwall(from + "--codec zfp --lossless -o " + zfp);
    ASSERT_EQ(lossless.status, 0) << lossless.out;
    EXPECT_LE(std::filesystem::file_size(zfp), voxels.size() + voxels.size() / 256 + 4096 + 4096);
  }
}

// `compress` reads raw, NRRD and NIfTI inputs a slab at a time: vq and svmm compress a volume
// larger than the memory it may use, and give back every voxel; ksvd compresses it too. The
// raw codec, whose output alone is larger than the limit, fails with one line and leaves no file.
// The limit is RLIMIT_DATA (prlimit --data: the process's private writable memory, about 100 MiB of
// which are the libraries' and threads' own before any voxel), not the address space, which the
// mapped libraries fill.
TEST(Cli, CompressStreamsAVolumeLargerThanItsMemoryLimit) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer maps its shadow memory as data: a data limit cannot apply";
#endif
  if (std::system("prlimit --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "no prlimit";
  test::TempDir dir;
  const std::string input = dir.path("big.raw");
  // 704^3 uint8: 332.8 MiB, half as much again as the 224 MiB limit.
  ASSERT_EQ(runVoxwall("generate shepp-logan --size 704 -o " + input).status, 0);
  ASSERT_EQ(std::filesystem::file_size(input), std::uintmax_t(704) * 704 * 704);
  const std::string limited = "prlimit --data=" + std::to_string(224 << 20) + " ";
  const std::string layout = " --dims 704,704,704 --type uint8 -q";
  const CliRun vq =
      runLimited(limited, "compress " + input + layout + " --codec vq -o " + dir.path("big.vwz"));
  ASSERT_EQ(vq.status, 0) << vq.out;
  ASSERT_EQ(runVoxwall("decompress " + dir.path("big.vwz") + " -o " + dir.path("back.raw")).status,
            0);
  EXPECT_EQ(std::system(("cmp -s " + input + " " + dir.path("back.raw")).c_str()), 0);
  // svmm builds its levels from windows of slices and writes its base level from a second pass.
  const CliRun svmm = runLimited(
      limited, "compress " + input + layout + " --codec svmm -o " + dir.path("svmm.vwz"));
  ASSERT_EQ(svmm.status, 0) << svmm.out;
  ASSERT_EQ(runVoxwall("decompress " + dir.path("svmm.vwz") + " -o " + dir.path("back.raw")).status,
            0);
  EXPECT_EQ(std::system(("cmp -s " + input + " " + dir.path("back.raw")).c_str()), 0);
  // ksvd reads a row of bricks of the volume and of its level 1 at a time, and holds the levels
  // above (1/56 of the voxels, as floats). Lossy: its file decodes to the volume's size.
  const CliRun k =
      runLimited(limited, "compress " + input + layout +
                              " --codec ksvd --atoms 64 --iterations 3 -o " + dir.path("k.vwz"));
  ASSERT_EQ(k.status, 0) << k.out;
  ASSERT_EQ(runVoxwall("decompress " + dir.path("k.vwz") + " -o " + dir.path("back.raw")).status,
            0);
  EXPECT_EQ(std::filesystem::file_size(dir.path("back.raw")), std::uintmax_t(704) * 704 * 704);

  expectOneLineError(
      runLimited(limited, "compress " + input + layout + " --codec raw -o " + dir.path("raw.vwz")),
      "voxwall: " + input + ": not enough memory to compress it with codec raw");
  EXPECT_FALSE(std::filesystem::exists(dir.path("raw.vwz")));
}

TEST(Cli, RenderWritesPngFrames) {
  test::TempDir dir;
  const CliRun r = runVoxwall(
      "render generated:shepp-logan:40 --size 48x32 --frames 2 --shading --out " + dir.path("f"));
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* f : {"f/frame_00000.png", "f/frame_00001.png"}) {
    const auto img = voxwall::readImage(dir.path(f));
    EXPECT_EQ(img.width, 48);
    EXPECT_EQ(img.height, 32);
  }
  EXPECT_NE(r.out.find("Msamples/s"), std::string::npos);
}

// The ray lattice from the command line: -v says what each frame cast; a magnified view casts
// fewer rays than pixels by default and one a pixel with --exact; wrong strides are refused.
TEST(Cli, RenderVerboseCountsTheRaysOfTheLattice) {
  const std::string base =
      "render generated:shepp-logan:32 --size 400x300 --camera 30,20,1.5 --no-write -v ";
  auto rays = [](const std::string& out) {
    const auto at = out.find(" rays for 120000 pixels (ray lattice ");
    EXPECT_NE(at, std::string::npos) << out;
    const auto start = out.rfind(", ", at);
    return at == std::string::npos ? 0ull : std::stoull(out.substr(start + 2, at - start - 2));
  };
  const CliRun lattice = runVoxwall(base);
  ASSERT_EQ(lattice.status, 0) << lattice.out;
  EXPECT_LT(rays(lattice.out), 120000ull);
  EXPECT_NE(lattice.out.find("refined above 8 levels), step "), std::string::npos) << lattice.out;
  // By default the step comes from the error budget, and the job says what it picked.
  EXPECT_NE(lattice.out.find(" for the 50 dB error budget (the first view on a "),
            std::string::npos)
      << lattice.out;
  const CliRun exact = runVoxwall(base + "--exact");
  ASSERT_EQ(exact.status, 0) << exact.out;
  EXPECT_EQ(rays(exact.out), 120000ull);
  EXPECT_NE(exact.out.find("(ray lattice 1, refined above 8 levels), step 0.25 voxels\n"),
            std::string::npos)
      << exact.out;
  EXPECT_EQ(exact.out.find("error budget"), std::string::npos) << exact.out;
  expectOneLineError(runVoxwall(base + "--step fine"),
                     "voxwall: --step: expected auto or a step in (0, 8] voxels, not 'fine'");
  expectOneLineError(runVoxwall(base + "--lattice 3"),
                     "voxwall: --lattice: expected auto or a power of two up to 16, not '3'");
  expectOneLineError(runVoxwall(base + "--exact --lattice 4"),
                     "voxwall: --exact casts a ray a pixel: it takes no --lattice 4");
  expectOneLineError(runVoxwall(base + "--refine-above 300"),
                     "voxwall: --refine-above must be in [0, 255] levels");
}

TEST(Cli, CorruptVwzFailsWithOneLine) {
  test::TempDir dir;
  const auto vwz = dir.path("m.vwz");
  ASSERT_EQ(runVoxwall("generate menger --level 2 -o " + vwz).status, 0);
  std::string bytes = test::readFile(vwz);
  bytes[bytes.size() - 10] ^= 0x40;
  test::writeFile(dir.path("bad.vwz"), bytes);
  expectOneLineError(runVoxwall("info " + dir.path("bad.vwz")),
                     "voxwall: " + dir.path("bad.vwz") + ": section");
  expectOneLineError(runVoxwall("render " + dir.path("bad.vwz") + " --out " + dir.path("f")),
                     "voxwall: " + dir.path("bad.vwz") + ": section");
  test::writeFile(dir.path("short.vwz"), bytes.substr(0, 200));
  expectOneLineError(runVoxwall("info " + dir.path("short.vwz")),
                     "voxwall: " + dir.path("short.vwz") + ": ");
  EXPECT_FALSE(std::filesystem::exists(dir.path("f/frame_00000.png")));
}

// A container with a codec id this build does not carry (a later voxwall's file): `info` shows
// what the container says and names the id; `decompress` and `render` refuse it with one line.
TEST(Cli, AnUnknownCodecIdIsNamedNotCrashedOn) {
  test::TempDir dir;
  std::uint32_t unknown = 1;  // the first id no codec of this build has
  while (codec::findCodec(codec::CodecId(unknown))) ++unknown;
  const std::string id = "id " + std::to_string(unknown);
  codec::CompressedVolume c;
  c.info.codec = codec::CodecId(unknown);
  c.info.dims = {4, 4, 4};
  c.sections.push_back({1, std::vector<std::byte>(64)});
  const std::string path = dir.path("future.vwz");
  codec::writeContainer(c, path);
  const auto info = runVoxwall("info " + path);
  EXPECT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("codec       " + id + ", not in this build (it has: raw, "),
            std::string::npos)
      << info.out;
  EXPECT_NE(info.out.find("dims        4 x 4 x 4"), std::string::npos) << info.out;
  for (const std::string& command : {"decompress " + path + " -o " + dir.path("x.nrrd"),
                                     "render " + path + " --size 8x8 --no-write"})
    expectOneLineError(runVoxwall(command),
                       "voxwall: " + path + ": unknown codec " + id + " (this build has: raw, ");
}

TEST(Cli, BadArgumentsGiveOneLine) {
  expectOneLineError(runVoxwall("render generated:menger:2 --size 12by9"), "voxwall: --size");
  expectOneLineError(runVoxwall("render generated:menger:2 --tf nosuchpreset"),
                     "voxwall: unknown transfer-function preset");
  expectOneLineError(runVoxwall("render /nonexistent.nii"),
                     "voxwall: /nonexistent.nii: no such file");
  expectOneLineError(runVoxwall("compress generated:menger:2 --codec nosuch -o /tmp/x.vwz"),
                     "voxwall: unknown codec 'nosuch'");
  expectOneLineError(runVoxwall("compress generated:menger:2 --quality 90 -o /tmp/x.vwz"),
                     "voxwall: --quality needs --codec svmm");
  // A flag two codecs take names both.
  expectOneLineError(runVoxwall("compress generated:menger:2 --iterations 3 -o /tmp/x.vwz"),
                     "voxwall: --iterations needs --codec ksvd or tvq");
  expectOneLineError(runVoxwall("compress generated:menger:2 --codec ksvd --block 5 -o /tmp/x.vwz"),
                     "voxwall: --block must be 4, 6 or 8, not 5");
  expectOneLineError(
      runVoxwall("compress generated:menger:2 --codec ksvd --coreset 2.5 -o /tmp/x.vwz"),
      "voxwall: --coreset must be a whole count");
  expectOneLineError(
      runVoxwall(
          "compress generated:menger:3 --codec ksvd --bits-per-voxel 0.001 -q -o /tmp/x.vwz"),
      "voxwall: --bits-per-voxel 0.001 is below the smallest ksvd file");
  expectOneLineError(
      runVoxwall("compress generated:menger:2 --codec svmm --block-width 3 -o /tmp/x.vwz"),
      "voxwall: --block-width must be a power of two in 2..64 or 'stepped'");
  expectOneLineError(
      runVoxwall("render generated:menger:2 --lod --size 8x8 --no-write"),
      "voxwall: --sampling nearest, --lod and --lod-under-pressure need a volume with mip "
      "levels (compress it with --codec svmm, ksvd)");
  expectOneLineError(
      runVoxwall("render generated:menger:2 --lod-under-pressure --size 8x8 --no-write"),
      "voxwall: --sampling nearest, --lod and --lod-under-pressure need a volume with mip");
  expectOneLineError(
      runVoxwall("compress generated:menger:2 --codec vq --codebook bogus -o /tmp/x.vwz"),
      "voxwall: --codebook must be");
  expectOneLineError(runVoxwall("compress generated:menger:2 --reduction 4 -o /tmp/x.vwz"),
                     "voxwall: --reduction needs --codec vq");
  expectOneLineError(
      runVoxwall(
          "compress generated:menger:2 --codec vq --reduction 4 --bits-per-voxel 1 -o /tmp/x.vwz"),
      "voxwall: give --reduction or --bits-per-voxel, not both");
  EXPECT_NE(runVoxwall("render --no-such-flag").status, 0);
}

TEST(Cli, WallPageAndInteractiveFlagsAreChecked) {
  const std::string wall = std::string(VOXWALL_WALLS_DIR) + "/ci-2x2.json";
  expectOneLineError(runVoxwall("render generated:menger:2 --size 8x8 --no-write "
                                "--interactive-step 0"),
                     "voxwall: --interactive-step must be in [1, 16]");
  expectOneLineError(runVoxwall("render generated:menger:2 --size 8x8 --no-write --settle -1"),
                     "voxwall: --settle must be in [0, 3600] seconds");
  expectOneLineError(runVoxwall("sink --wall " + wall + " --http nonsense --no-stdin"),
                     "voxwall: --http");
  expectOneLineError(runVoxwall("sink --wall " + wall + " --http-origin http://x --no-stdin"),
                     "voxwall: --http-origin goes with --http");
  expectOneLineError(
      runVoxwall("sink --wall " + wall + " --http 127.0.0.1:0 --http-origin evil --no-stdin"),
      "voxwall: --http-origin 'evil': expected http://HOST[:PORT]");
  expectOneLineError(runVoxwall("sink --wall " + wall + " --max-viewers 0 --no-stdin"),
                     "voxwall: --max-viewers must be in [1, 4096]");
  // The page's address is printed, and --help says what the flags do.
  const auto help = runVoxwall("sink --help");
  EXPECT_NE(help.out.find("--http"), std::string::npos);
  EXPECT_NE(runVoxwall("render --help").out.find("--interactive-step"), std::string::npos);
  EXPECT_NE(runVoxwall("render --help").out.find("still"), std::string::npos);
}

TEST(Cli, VqCompressInfoDecompressRender) {
  test::TempDir dir;
  const std::string vwz = dir.path("sl.vwz");
  const CliRun c =
      runVoxwall("compress generated:shepp-logan:24 --codec vq --reduction 4 -q -o " + vwz);
  ASSERT_EQ(c.status, 0) << c.out;
  EXPECT_NE(c.out.find("lossy: 1/4 of the unique bricks, PSNR"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("codewords by predictor: none "), std::string::npos) << c.out;
  const CliRun info = runVoxwall("info " + vwz);
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("codec       vq"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("quality     lossy, 1/4"), std::string::npos) << info.out;
  const CliRun d = runVoxwall("decompress " + vwz + " -o " + dir.path("sl.nrrd"));
  EXPECT_EQ(d.status, 0) << d.out;
  const CliRun r = runVoxwall("render " + vwz + " --size 32x24 --out " + dir.path("frames"));
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_TRUE(std::filesystem::exists(dir.path("frames/frame_00000.png")));
}

namespace {
// Renders `vwz` once with each of `extras` appended to a small render command: each succeeds and
// writes a frame.
void expectRendersWith(const std::string& vwz, const test::TempDir& dir,
                       std::initializer_list<const char*> extras) {
  for (const char* extra : extras) {
    const CliRun r =
        runVoxwall("render " + vwz + " --size 32x24 --out " + dir.path("frames") + extra);
    EXPECT_EQ(r.status, 0) << extra << ": " << r.out;
  }
  EXPECT_TRUE(std::filesystem::exists(dir.path("frames/frame_00000.png")));
}
}  // namespace

TEST(Cli, SvmmCompressInfoDecompressRender) {
  test::TempDir dir;
  const std::string vwz = dir.path("sl.vwz");
  const CliRun c = runVoxwall(
      "compress generated:shepp-logan:40 --codec svmm --block-width stepped --root-width 8 -q -o " +
      vwz);
  ASSERT_EQ(c.status, 0) << c.out;
  EXPECT_NE(c.out.find("levels (block widths 2, 4, root;"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("quality 100 (delta 0 of the value range): lossless"), std::string::npos)
      << c.out;
  const CliRun info = runVoxwall("info " + vwz);
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("codec       svmm"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("levels      3 (block widths 2, 4, root, stepped; root width 8)"),
            std::string::npos)
      << info.out;
  EXPECT_NE(info.out.find("quality     100, lossless"), std::string::npos) << info.out;
  // Lossless: decompressing gives back the generated volume's voxels.
  ASSERT_EQ(runVoxwall("decompress " + vwz + " -o " + dir.path("sl.nrrd")).status, 0);
  ASSERT_EQ(runVoxwall("compress generated:shepp-logan:40 -q -o " + dir.path("raw.vwz")).status, 0);
  ASSERT_EQ(runVoxwall("decompress " + dir.path("raw.vwz") + " -o " + dir.path("raw.nrrd")).status,
            0);
  EXPECT_EQ(test::readFile(dir.path("sl.nrrd")), test::readFile(dir.path("raw.nrrd")));
  const CliRun lossy = runVoxwall(
      "compress generated:shepp-logan:40 --codec svmm --quality 80 "
      "--base-compression -q -o " +
      dir.path("lossy.vwz"));
  ASSERT_EQ(lossy.status, 0) << lossy.out;
  EXPECT_NE(lossy.out.find("base blocks compressed"), std::string::npos) << lossy.out;
  EXPECT_NE(lossy.out.find("PSNR"), std::string::npos) << lossy.out;
  expectRendersWith(
      vwz, dir, {"", " --sampling nearest", " --lod --shading", " --shading --gradients samples"});
  expectOneLineError(runVoxwall("render " + vwz + " --sampling cubic --size 8x8 --no-write"),
                     "voxwall: --sampling: expected trilinear or nearest");
  expectOneLineError(runVoxwall("render " + vwz +
                                " --shading --gradients sobel --size 8x8 "
                                "--no-write"),
                     "voxwall: --gradients: expected cell or samples");
}

TEST(Cli, KsvdPyramidInfoAndLevelOfDetailRender) {
  test::TempDir dir;
  const std::string vwz = dir.path("ml.vwz");
  const CliRun c = runVoxwall(
      "compress generated:marschner-lobb:40 --codec ksvd --block 4 --atoms 16 --iterations 2 -q "
      "-o " +
      vwz);
  ASSERT_EQ(c.status, 0) << c.out;
  EXPECT_NE(c.out.find("2 levels (--lod)"), std::string::npos) << c.out;
  EXPECT_EQ(c.out.find("the coarser levels take"), std::string::npos) << c.out;
  // With a size target the report says what the pyramid takes of it.
  const CliRun sized = runVoxwall(
      "compress generated:marschner-lobb:40 --codec ksvd --block 4 --atoms 16 --iterations 2 "
      "--bits-per-voxel 2 -q -o " +
      dir.path("sized.vwz"));
  ASSERT_EQ(sized.status, 0) << sized.out;
  EXPECT_NE(sized.out.find("the coarser levels take "), std::string::npos) << sized.out;
  EXPECT_NE(sized.out.find("--levels 1 gives them to level 0"), std::string::npos) << sized.out;
  const CliRun info = runVoxwall("info " + vwz);
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("2 (render --lod), PSNR 40x40x40: "), std::string::npos) << info.out;
  EXPECT_NE(info.out.find(", 20x20x20: "), std::string::npos) << info.out;
  expectRendersWith(vwz, dir, {" --sampling nearest", " --lod --shading"});
  if (node::cpuPacketLanes() > 1) {
    // Two pages of room for a volume of eight: later frames sample coarser where pages are not
    // resident, and -v counts those samples.
    const CliRun pressed = runVoxwall("render " + vwz +
                                      " --size 40x30 --frames 3 --no-write -v "
                                      "--decode-cache 100K --lod-under-pressure");
    ASSERT_EQ(pressed.status, 0) << pressed.out;
    std::uint64_t coarse = 0;
    for (std::size_t at = pressed.out.find(" resident, "); at != std::string::npos;
         at = pressed.out.find(" resident, ", at + 1)) {
      unsigned long long n = 0;
      if (std::sscanf(pressed.out.c_str() + at, " resident, %llu samples from coarser", &n) == 1)
        coarse += n;
    }
    EXPECT_GT(coarse, 0u) << pressed.out;
  }
  const CliRun flat = runVoxwall(
      "compress generated:marschner-lobb:40 --codec ksvd --levels 1 --atoms 16 --iterations 2 -q "
      "-o " +
      dir.path("flat.vwz"));
  ASSERT_EQ(flat.status, 0) << flat.out;
  EXPECT_EQ(flat.out.find("levels (--lod)"), std::string::npos) << flat.out;
  expectOneLineError(
      runVoxwall("compress generated:menger:2 --codec ksvd --levels 9 -o /tmp/x.vwz"),
      "voxwall: --levels");
}

TEST(Cli, TvqCompressInfoProgressiveRender) {
  test::TempDir dir;
  const std::string vwz = dir.path("sl.vwz");
  const CliRun c = runVoxwall(
      "compress generated:shepp-logan:40 --codec tvq --transform dct --codebook-bits 12 "
      "--iterations 2 --subvolume 32 -q -o " +
      vwz);
  ASSERT_EQ(c.status, 0) << c.out;
  EXPECT_NE(c.out.find("DCT, 1000 blocks in 8 sub-volume(s)"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("PSNR per progressive level: mean "), std::string::npos) << c.out;
  const CliRun info = runVoxwall("info " + vwz);
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("progressive dc (mean) "), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("(render --progressive LEVEL)"), std::string::npos) << info.out;
  expectRendersWith(vwz, dir, {" --progressive dc", " --progressive bp --shading"});
  expectOneLineError(runVoxwall("render " + vwz + " --progressive hp --size 8x8 --no-write"),
                     "voxwall: --progressive must be dc, lp, bp or all, not 'hp'");
  expectOneLineError(runVoxwall("render generated:menger:2 --progressive dc --size 8x8 --no-write"),
                     "voxwall: --progressive needs a .vwz file");
  const std::string vq = dir.path("vq.vwz");
  ASSERT_EQ(runVoxwall("compress generated:menger:2 --codec vq -q -o " + vq).status, 0);
  expectOneLineError(runVoxwall("render " + vq + " --progressive dc --size 8x8 --no-write"),
                     "voxwall: --progressive needs a file of codec tvq; " + vq + " is vq");
  expectOneLineError(runVoxwall("compress generated:menger:2 --codec tvq --transform wavelet "
                                "-o /tmp/x.vwz"),
                     "voxwall: --transform must be klt or dct, not 'wavelet'");
  expectOneLineError(runVoxwall("compress generated:menger:2 --codec tvq --codebook-bits 12 "
                                "--bits-per-voxel 1 -o /tmp/x.vwz"),
                     "voxwall: --codebook-bits and --bits-per-voxel exclude each other");
  expectOneLineError(
      runVoxwall("compress generated:menger:2 --codec tvq --subvolume 30 -o /tmp/x.vwz"),
      "voxwall: --subvolume must be a multiple of 4, not 30");
}

TEST(Cli, CudaBackendWithoutADeviceFailsCleanly) {
  const CliRun r = runVoxwall("render generated:menger:2 --size 8x8 --no-write --backend cuda");
  if (r.status == 0) GTEST_SKIP() << "a CUDA device is present";
  expectOneLineError(r, "voxwall: cuda: ");
}

TEST(Cli, TiledRenderWritesTheSameFrame) {
  test::TempDir dir;
  const std::string common = "render generated:shepp-logan:32 --size 37x23 --shading -q --out ";
  ASSERT_EQ(runVoxwall(common + dir.path("one")).status, 0);
  ASSERT_EQ(runVoxwall(common + dir.path("tiled") + " --tiles 3x2").status, 0);
  EXPECT_EQ(voxwall::readImage(dir.path("one/frame_00000.png")).pixels,
            voxwall::readImage(dir.path("tiled/frame_00000.png")).pixels);
  expectOneLineError(runVoxwall(common + dir.path("bad") + " --tiles 40x1"),
                     "voxwall: tile grid 40x1");
}

TEST(Cli, TfRangeMovesTheTransferFunction) {
  test::TempDir dir;
  const std::string common = "render generated:shepp-logan:32 --size 24x24 -q --tf grey --out ";
  ASSERT_EQ(runVoxwall(common + dir.path("a")).status, 0);
  // Stretched far above the data: everything is transparent.
  ASSERT_EQ(runVoxwall(common + dir.path("b") + " --tf-range 1000,2000").status, 0);
  const auto a = voxwall::readImage(dir.path("a/frame_00000.png"));
  const auto b = voxwall::readImage(dir.path("b/frame_00000.png"));
  EXPECT_NE(a.pixels, b.pixels);
  for (auto p : b.pixels) ASSERT_EQ(p, 0xff000000u);  // black background, nothing in front
  expectOneLineError(runVoxwall(common + dir.path("c") + " --tf-range 5,1"), "voxwall: --tf-range");
}

TEST(Cli, InfoDescribesAPlainVolumeFile) {
  test::TempDir dir;
  ASSERT_EQ(runVoxwall("generate menger --level 2 -o " + dir.path("m.nrrd")).status, 0);
  const CliRun r = runVoxwall("info " + dir.path("m.nrrd"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("9 x 9 x 9"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("uint8"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("0 .. 255"), std::string::npos) << r.out;
}

TEST(Cli, DistributedOptionsAreCheckedWithOneLine) {
  const std::string render = "render generated:shepp-logan:16 --size 32x24 --no-write ";
  expectOneLineError(runVoxwall(render + "--tiles 2x2 --balance dynamic"),
                     "voxwall: --tiles cuts the screen statically");
  expectOneLineError(runVoxwall(render + "--balance fair"), "voxwall: --balance: expected");
  expectOneLineError(runVoxwall(render + "--master-only"),
                     "voxwall: --master-only needs at least 2 ranks");
  expectOneLineError(runVoxwall(render + "--memory-budget lots"), "voxwall: --memory-budget:");
  expectOneLineError(runVoxwall(render + "--memory-budget 1K"), "voxwall: needs ");
  expectOneLineError(runVoxwall(render + "--watchdog 0"), "voxwall: --watchdog must be");
  expectOneLineError(runVoxwall(render + "--resume"), "voxwall: --resume needs frames on disk");
  expectOneLineError(runVoxwall(render + "--path nowhere.json"), "voxwall: nowhere.json: ");
  expectOneLineError(runVoxwall(render + "--pan 1"), "voxwall: --pan: expected X,Y");
}

TEST(Cli, DryRunPrintsTheTileMapAndWritesNothing) {
  test::TempDir dir;
  const CliRun r = runVoxwall(
      "render generated:shepp-logan:16 --size 32x24 --tiles 2x2 --dry-run "
      "--out " +
      dir.path("frames"));
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("rank 0 on localhost: needs "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("tiles: 16x12+0+0 16x12+16+0 16x12+0+12 16x12+16+12"), std::string::npos)
      << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.path("frames")));
}

TEST(Cli, OrbitZoomPathApproachesTheVolume) {
  test::TempDir dir;
  const CliRun r = runVoxwall(
      "render generated:shepp-logan:24 --size 40x30 --frames 4 --path orbit-zoom --zoom-to 1.0 "
      "-q --out " +
      dir.path("f"));
  ASSERT_EQ(r.status, 0) << r.out;
  // The zoomed frame covers more pixels than the first one.
  auto covered = [](const voxwall::Image& im) {
    return std::count_if(im.pixels.begin(), im.pixels.end(),
                         [](std::uint32_t p) { return (p & 0xffffffu) != 0; });
  };
  EXPECT_GT(covered(voxwall::readImage(dir.path("f/frame_00003.png"))),
            covered(voxwall::readImage(dir.path("f/frame_00000.png"))));
}

TEST(Cli, WallAndSinkOptionsAreCheckedWithOneLine) {
  test::TempDir dir;
  const std::string wall = std::string(VOXWALL_WALLS_DIR) + "/ci-2x2.json";
  const std::string render = "render generated:shepp-logan:16 --no-write ";
  expectOneLineError(runVoxwall(render + "--sink 127.0.0.1:7400"), "voxwall: --sink needs --wall");
  expectOneLineError(runVoxwall(render + "--token abc"), "voxwall: --token goes with --sink");
  expectOneLineError(runVoxwall(render + "--wall " + wall + " --size 64x64"),
                     "voxwall: --size and --wall both set the screen");
  expectOneLineError(runVoxwall(render + "--wall " + wall +
                                " --sink 127.0.0.1:7400 "
                                "--tile-codec png"),
                     "voxwall: --tile-codec: expected");
  expectOneLineError(runVoxwall(render + "--wall " + wall + " --sink localhost"),
                     "voxwall: --sink: expected HOST:PORT");
  test::writeFile(dir.path("overlap.json"),
                  R"({"displays": [{"name": "a", "x": 0, "y": 0, "width": 10, "height": 10},
                                   {"name": "b", "x": 5, "y": 5, "width": 10, "height": 10}]})");
  expectOneLineError(runVoxwall("sink --wall " + dir.path("overlap.json")),
                     "voxwall: " + dir.path("overlap.json") + ": display 'b' overlaps");
  expectOneLineError(runVoxwall("sink --wall " + wall + " --listen 10.1.2.3.4:80"),
                     "voxwall: --listen: '10.1.2.3.4' is not an IP address");
  expectOneLineError(runVoxwall("sink --wall " + wall + " --max-peers 0"),
                     "voxwall: --max-peers must be in [1, 65536]");
  expectOneLineError(runVoxwall("sink --wall " + wall + " --hello-timeout-ms 0"),
                     "voxwall: --hello-timeout-ms must be in [1, 600000]");
  // Ranks say KeepAlive every 5 s: a shorter idle time would drop them between two.
  expectOneLineError(runVoxwall("sink --wall " + wall + " --peer-idle 5"),
                     "voxwall: --peer-idle 5: expected 10 to 86400 seconds");
  // Memory for open frames must hold at least one frame of the wall (bigeye: 99 MiB).
  expectOneLineError(
      runVoxwall("sink --wall " + std::string(VOXWALL_WALLS_DIR) + "/bigeye.json --pending-mib 10"),
      "voxwall: memory for open frames (--pending-mib) is 10 MiB, less than one "
      "frame of this wall (99 MiB)");
  // A wall rendered without a sink: the frame has the wall's size.
  const CliRun r =
      runVoxwall("render generated:shepp-logan:16 -q --wall " + wall + " --out " + dir.path("f"));
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(voxwall::readImage(dir.path("f/frame_00000.png")).width, 196);
}

TEST(Cli, EitherSurfaceOfATwoSurfaceTideConfigurationRenders) {
  test::TempDir dir;
  const auto two = dir.path("two.json");
  test::writeFile(two, R"({"surfaces": [
      {"displayWidth": 32, "displayHeight": 24, "screenCountX": 2, "bezelWidth": 4},
      {"displayWidth": 20, "displayHeight": 16, "displaysPerScreenY": 2, "bezelHeight": -2}]})");
  const std::string render = "render generated:shepp-logan:16 -q --wall " + two;
  const CliRun first = runVoxwall(render + " --out " + dir.path("s0"));
  ASSERT_EQ(first.status, 0) << first.out;
  const auto image0 = voxwall::readImage(dir.path("s0/frame_00000.png"));
  EXPECT_EQ(image0.width, 68);
  EXPECT_EQ(image0.height, 24);
  const CliRun second = runVoxwall(render + " --surface 1 --out " + dir.path("s1"));
  ASSERT_EQ(second.status, 0) << second.out;
  const auto image1 = voxwall::readImage(dir.path("s1/frame_00000.png"));
  EXPECT_EQ(image1.width, 20);
  EXPECT_EQ(image1.height, 30);

  const CliRun dry =
      runVoxwall("render generated:shepp-logan:16 --wall " + two + " --surface 1 --dry-run");
  ASSERT_EQ(dry.status, 0) << dry.out;
  EXPECT_NE(dry.out.find("surface 0: 2 display(s), virtual screen 68x24"), std::string::npos)
      << dry.out;
  EXPECT_NE(dry.out.find("surface 1: 2 display(s), virtual screen 20x30"), std::string::npos)
      << dry.out;
  EXPECT_NE(dry.out.find("(overlapping displays) (rendered)"), std::string::npos) << dry.out;

  expectOneLineError(runVoxwall(render + " --surface 2 --no-write"),
                     "voxwall: " + two + ": --surface 2: the file has 2 surface(s), 0 to 1");
  expectOneLineError(runVoxwall("sink --wall " + two + " --surface 2"),
                     "voxwall: " + two + ": --surface 2: the file has 2 surface(s), 0 to 1");
  expectOneLineError(runVoxwall("render generated:shepp-logan:16 --no-write --surface 1"),
                     "voxwall: --surface needs --wall");
}

// ParaView's presets as ParaView applies them, on the MRI (Debian's mricron-data, which the
// README's commands install).
TEST(Cli, ParaViewPresetsAreAppliedAsParaViewDoes) {
  const std::string mri = "/usr/share/mricron/templates/ch2better.nii.gz";
  if (!std::filesystem::exists(mri)) GTEST_SKIP() << mri << " not installed (mricron-data)";
  test::TempDir dir;
  const auto presets = dir.path("presets.json");
  // ParaView's own "Cool to Warm" (normalized, Diverging, no opacity) and a map with opacity.
  test::writeFile(presets, R"([
    {"Name": "Cool to Warm", "ColorSpace": "Diverging", "NanColor": [1, 1, 0],
     "RGBPoints": [0, 0.231373, 0.298039, 0.752941, 1, 0.705882, 0.0156863, 0.14902]},
    {"Name": "Ramp", "ColorSpace": "RGB", "RGBPoints": [0, 0, 0, 0, 1, 1, 1, 1],
     "Points": [0, 0, 0.5, 0, 0.6, 0, 0.5, 0, 1, 1, 0.5, 0]}])");
  const std::string render = "render " + mri + " --size 160x120 ";

  // Several maps and no name: refused, with the names.
  expectOneLineError(runVoxwall(render + "--no-write --tf " + presets),
                     "voxwall: " + presets + ": holds 2 colour maps ('Cool to Warm', 'Ramp')");
  const CliRun list = runVoxwall("tf list " + presets);
  ASSERT_EQ(list.status, 0) << list.out;
  EXPECT_NE(list.out.find("Cool to Warm\tDiverging\t2 points\t0..1 normalized\tno opacity"),
            std::string::npos)
      << list.out;
  EXPECT_NE(list.out.find("Ramp\tRGB"), std::string::npos) << list.out;

  // The normalized map is stretched over the data: blue, light and red, not one colour.
  const CliRun coolWarm =
      runVoxwall(render + "--tf '" + presets + ":Cool to Warm' --out " + dir.path("cw"));
  ASSERT_EQ(coolWarm.status, 0) << coolWarm.out;
  EXPECT_NE(coolWarm.out.find("'Cool to Warm' is normalized: stretched over the data range"),
            std::string::npos)
      << coolWarm.out;
  const auto image = voxwall::readImage(dir.path("cw/frame_00000.png"));
  int covered = 0, cool = 0, warm = 0, light = 0;
  for (const std::uint32_t p : image.pixels) {
    const int r = int(p & 255), g = int((p >> 8) & 255), b = int((p >> 16) & 255);
    if (r + g + b < 12) continue;
    ++covered;
    cool += b > r + 5;
    warm += r > b + 5;
    light += g > 128;  // the diverging map's light middle (its red end has green 4)
  }
  ASSERT_GT(covered, 2000);
  EXPECT_GT(cool, covered / 200) << "cool " << cool << " of " << covered;
  EXPECT_GT(warm, covered / 2) << "warm " << warm << " of " << covered;
  EXPECT_GT(light, covered / 2) << "light " << light << " of " << covered;

  // --opacity: colours from one map, the opacity curve of another. Opacity alone decides alpha,
  // so the result's alpha is that of the other map's own render, and not the default curve's.
  auto alphaOf = [](const voxwall::Image& im) {
    std::vector<int> a;
    for (const std::uint32_t p : im.pixels) a.push_back(int(p >> 24));
    return a;
  };
  const std::string straight = render + "-q --background none ";
  ASSERT_EQ(runVoxwall(straight + "--tf '" + presets + ":Cool to Warm' --opacity " + presets +
                       ":Ramp --out " + dir.path("mixed"))
                .status,
            0);
  ASSERT_EQ(runVoxwall(straight + "--tf " + presets + ":Ramp --out " + dir.path("ramp")).status, 0);
  ASSERT_EQ(
      runVoxwall(straight + "--tf '" + presets + ":Cool to Warm' --out " + dir.path("own")).status,
      0);
  const auto mixed = alphaOf(voxwall::readImage(dir.path("mixed/frame_00000.png")));
  EXPECT_EQ(mixed, alphaOf(voxwall::readImage(dir.path("ramp/frame_00000.png"))));
  EXPECT_NE(mixed, alphaOf(voxwall::readImage(dir.path("own/frame_00000.png"))));
  expectOneLineError(
      runVoxwall(render + "--no-write --tf mri --opacity '" + presets + ":Cool to Warm'"),
      "voxwall: --opacity " + presets + ":Cool to Warm: it has no opacity");
}

// --simd: the render line names the backend's packets or one ray at a time, and both give the
// same picture (Packets.* checks every view; here through the command line).
TEST(Cli, SimdChoosesPacketsOrOneRayAtATime) {
  expectOneLineError(runVoxwall("render generated:menger:2 --size 8x8 --no-write --simd maybe"),
                     "voxwall: --simd");
  test::TempDir dir;
  std::string lines[2];
  for (int i = 0; i < 2; ++i) {
    const std::string simd = i == 0 ? "on" : "off";
    const CliRun r = runVoxwall("render generated:shepp-logan:24 --size 40x30 --shading --simd " +
                                simd + " --out " + dir.path(simd));
    ASSERT_EQ(r.status, 0) << r.out;
    lines[i] = r.out;
  }
  if (node::cpuPacketLanes() > 1) {
    EXPECT_NE(lines[0].find(" packets of "), std::string::npos) << lines[0];
  }
  EXPECT_NE(lines[1].find("one ray at a time"), std::string::npos) << lines[1];
  const auto on = voxwall::readImage(dir.path("on") + "/frame_00000.png");
  const auto off = voxwall::readImage(dir.path("off") + "/frame_00000.png");
  EXPECT_LE(voxwall::compareImages(on, off).maxAbs, 1);
}

// --decode-cache: a wrong size is the one-line error; the dry run counts in what a rank needs the
// decoded pages its rays reach in the first frame (a 96^3 uint8 vq volume is 4^3 pages of 35^3
// bytes: they are cut 16 voxels off multiples of 32), capped by the budget, and the picture is
// the same with and without them.
TEST(Cli, DecodeCacheIsCountedAndKeepsThePicture) {
  expectOneLineError(
      runVoxwall("render generated:menger:2 --size 8x8 --no-write --decode-cache lots"),
      "voxwall: --decode-cache: expected a size");
  test::TempDir dir;
  const std::string vq = dir.path("sl.vwz");
  ASSERT_EQ(runVoxwall("compress generated:shepp-logan:96 --codec vq -q -o " + vq).status, 0);
  auto dryRun = [&](const std::string& cache, const std::string& camera = "30,20,2.6") {
    const CliRun r = runVoxwall("render " + vq + " --size 160x120 --dry-run --camera " + camera +
                                " --decode-cache " + cache);
    EXPECT_EQ(r.status, 0) << r.out;
    return r.out;
  };
  // The pages a dry run counts for rank 0, in pages of 35^3 bytes (-1: no such line).
  auto pagesOf = [](const std::string& out) {
    const auto at = out.find(", of it decoded pages ");
    if (at == std::string::npos) return -1.0;
    double value = 0;
    char unit[8] = {};
    if (std::sscanf(out.c_str() + at, ", of it decoded pages %lf %7[KMGi]B,", &value, unit) != 2)
      return -1.0;
    const double scale = unit[0] == 'K' ? 1024.0 : unit[0] == 'M' ? 1048576.0 : 1.0;
    return value * scale / (35.0 * 35.0 * 35.0);
  };
  if (node::cpuPacketLanes() > 1) {
    const double whole = pagesOf(dryRun("1G"));
    EXPECT_GE(whole, 0.99) << dryRun("1G");
    const int side = node::pages::pagesAlong(96);
    EXPECT_LE(whole, side * side * side + 0.01) << dryRun("1G");
    // From inside the volume, the rays reach fewer pages.
    const double inside = pagesOf(dryRun("1G", "30,20,0.3"));
    EXPECT_GE(inside, 0.99) << dryRun("1G", "30,20,0.3");
    EXPECT_LT(inside, whole) << dryRun("1G", "30,20,0.3");
    // 100K holds two pages.
    EXPECT_NE(dryRun("100K").find(", of it decoded pages 83.7 KiB, "), std::string::npos)
        << dryRun("100K");
    // The mapped .vwz is told apart from the rank's own memory: the file's size.
    EXPECT_NE(
        dryRun("100K").find(", mapped file " + humanBytes(double(std::filesystem::file_size(vq))) +
                            ", shared by the ranks on one host)"),
        std::string::npos)
        << dryRun("100K");
    // -v prints the rank's page cache each frame: hits, pages decoded, evicted, resident, the
    // samples that waited for another thread's page; and its memory, private and mapped.
    const CliRun v = runVoxwall("render " + vq + " --size 40x30 --frames 2 --no-write -v");
    EXPECT_EQ(v.status, 0) << v.out;
    EXPECT_NE(v.out.find("    decoded pages: "), std::string::npos) << v.out;
    EXPECT_NE(v.out.find(" evicted, "), std::string::npos) << v.out;
    EXPECT_NE(v.out.find(" samples waited for a page another thread decoded; "), std::string::npos)
        << v.out;
    EXPECT_NE(v.out.find("\n    private "), std::string::npos) << v.out;
    EXPECT_NE(v.out.find("rank 0 on "), std::string::npos) << v.out;
    // And how long rank 0 took to open the volume.
    EXPECT_NE(v.out.find("voxwall: rank 0 opened " + vq + " in "), std::string::npos) << v.out;
  }
  EXPECT_EQ(dryRun("off").find("decoded pages"), std::string::npos);
  EXPECT_EQ(dryRun("0").find("decoded pages"), std::string::npos);
  for (const std::string cache : {"off", "1G", "100K"})
    ASSERT_EQ(runVoxwall("render " + vq + " --size 40x30 --shading --decode-cache " + cache +
                         " --out " + dir.path(cache))
                  .status,
              0);
  const auto off = voxwall::readImage(dir.path("off") + "/frame_00000.png");
  for (const std::string cache : {"1G", "100K"})
    EXPECT_LE(voxwall::compareImages(voxwall::readImage(dir.path(cache) + "/frame_00000.png"), off)
                  .maxAbs,
              1)
        << cache;
}

// A DICOM folder as a CT user has it: info, compress and render read it; a folder of two series
// is refused in one line naming them, and --series picks one.
TEST(Cli, DicomSeriesAreReadAndChosenBySeriesUid) {
  test::TempDir dir;
  auto writeSeries = [&](const std::string& sub, const std::string& uid, int depth) {
    std::filesystem::create_directories(dir.root() / sub);
    for (int k = 0; k < depth; ++k) {
      test::DicomSlice s;
      s.columns = 16, s.rows = 12, s.isUnsigned = true, s.intercept = -1024;
      for (int i = 0; i < 16 * 12; ++i) s.pixels.push_back(std::int16_t(i * 10 + k));
      s.position = {0, 0, -1.25 * k};
      s.seriesUid = uid, s.description = sub;
      writeDicom(dir.path(sub + "/slice" + std::to_string((k * 5) % depth)), s);
    }
  };
  writeSeries("ct", "1.2.3.4.1", 8);
  const CliRun info = runVoxwall("info " + dir.path("ct"));
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("16 x 12 x 8"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("int16"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("1 x 1 x 1.25"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("-1024 .. 893"), std::string::npos) << info.out;
  const CliRun c = runVoxwall("compress " + dir.path("ct") + " -o " + dir.path("ct.vwz") + " -q");
  EXPECT_EQ(c.status, 0) << c.out;
  const CliRun r = runVoxwall("render " + dir.path("ct") + " --size 32x32 --frames 1 --out " +
                              dir.path("frames") + " -q");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_TRUE(std::filesystem::exists(dir.path("frames/frame_00000.png"))) << r.out;

  writeSeries("ct/scout", "1.2.3.4.2", 3);
  const CliRun two = runVoxwall("info " + dir.path("ct"));
  expectOneLineError(two,
                     "voxwall: " + dir.path("ct") + ": holds 2 series; choose one with --series");
  EXPECT_NE(two.out.find("1.2.3.4.2 \"ct/scout\" (CT, 3 files, 16x12)"), std::string::npos)
      << two.out;
  const CliRun picked = runVoxwall("info " + dir.path("ct") + " --series 1.2.3.4.2");
  ASSERT_EQ(picked.status, 0) << picked.out;
  EXPECT_NE(picked.out.find("16 x 12 x 3"), std::string::npos) << picked.out;
}

// The hu-* presets are on Hounsfield units whatever the data's range: a CT stored with an offset
// and --rescale gives the picture of the same CT in HU, without --rescale it gets a note; --window
// is the radiologist's level/width.
TEST(Cli, HounsfieldPresetsMeetHuThroughRescaleAndWindow) {
  test::TempDir dir;
  // A 24^3 ball: soft tissue (40 HU) inside a bone shell (1200 HU), in air.
  auto writeBall = [&](const std::string& sub, double intercept) {
    std::filesystem::create_directories(dir.root() / sub);
    for (int z = 0; z < 24; ++z) {
      test::DicomSlice s;
      s.columns = 24, s.rows = 24, s.isUnsigned = true, s.intercept = intercept;
      for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 24; ++x) {
          const double r = std::hypot(x - 11.5, y - 11.5, z - 11.5) / 10.0;
          const int hu = r > 1 ? -1000 : r > 0.8 ? 1200 : 40;
          s.pixels.push_back(std::int16_t(hu + 1024));
        }
      s.position = {0, 0, double(z)};
      writeDicom(dir.path(sub + "/" + std::to_string(z)), s);
    }
  };
  writeBall("hu", -1024);  // read as int16 HU
  writeBall("offset", 0);  // read as uint16 HU + 1024
  const std::string render = " --size 48x48 --frames 1 --camera 30,20,2.6 --out ";
  const CliRun hu =
      runVoxwall("render " + dir.path("hu") + " --tf hu-bone -q" + render + dir.path("a"));
  ASSERT_EQ(hu.status, 0) << hu.out;
  const CliRun rescaled = runVoxwall("render " + dir.path("offset") +
                                     " --tf hu-bone --rescale 1,-1024 -q" + render + dir.path("b"));
  ASSERT_EQ(rescaled.status, 0) << rescaled.out;
  const auto a = voxwall::readImage(dir.path("a/frame_00000.png"));
  const auto b = voxwall::readImage(dir.path("b/frame_00000.png"));
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  int worst = 0, lit = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    for (int c = 0; c < 32; c += 8)
      worst =
          std::max(worst, std::abs(int((a.pixels[i] >> c) & 255) - int((b.pixels[i] >> c) & 255)));
    lit += (a.pixels[i] & 255) > 40;
  }
  EXPECT_LE(worst, 2);
  EXPECT_GT(lit, 200);  // the bone shell shows

  // Without --rescale the offset volume holds no air in HU terms: said once.
  const CliRun noted =
      runVoxwall("render " + dir.path("offset") + " --tf hu-bone --no-write --size 16x16");
  ASSERT_EQ(noted.status, 0) << noted.out;
  EXPECT_NE(noted.out.find("'hu-bone' is on Hounsfield units, but this volume's values 24..2224 "
                           "reach no air"),
            std::string::npos)
      << noted.out;

  // --window CENTER,WIDTH is --tf-range CENTER-WIDTH/2,CENTER+WIDTH/2.
  ASSERT_EQ(runVoxwall("render " + dir.path("hu") + " --tf grey --window 40,400 -q" + render +
                       dir.path("w"))
                .status,
            0);
  ASSERT_EQ(runVoxwall("render " + dir.path("hu") + " --tf grey --tf-range -160,240 -q" + render +
                       dir.path("r"))
                .status,
            0);
  EXPECT_EQ(voxwall::readImage(dir.path("w/frame_00000.png")).pixels,
            voxwall::readImage(dir.path("r/frame_00000.png")).pixels);
  EXPECT_NE(
      runVoxwall("render " + dir.path("hu") + " --no-write --window 40,400 --tf-range 1,2").status,
      0);
  expectOneLineError(runVoxwall("render " + dir.path("hu") + " --no-write --window 40,-5"),
                     "voxwall: --window");
  expectOneLineError(runVoxwall("render " + dir.path("hu") + " --no-write --rescale 0,5"),
                     "voxwall: --rescale");
}

// A job whose tiles never reach the wall fails with one line instead of exiting 0: at the end
// of a short job, and within --sink-deadline of a long one. Port 1 has no sink (refused at once).
TEST(Cli, AStreamingJobWhoseTilesNeverReachTheWallFails) {
  const std::string wall = std::string(VOXWALL_WALLS_DIR) + "/ci-2x2.json";
  const std::string render =
      "render generated:menger:2 --wall " + wall + " --sink 127.0.0.1:1 --threads 1 -q ";
  expectOneLineError(runVoxwall(render + "--frames 3"),
                     "voxwall: wall sink 127.0.0.1:1: none of the 3 frame(s) reached it (rank 0: ");
  expectOneLineError(runVoxwall(render + "--frames 1000000 --sink-deadline 0.5"),
                     "voxwall: wall sink 127.0.0.1:1: no tiles reached it for 0.5 s (rank 0: ");
  expectOneLineError(runVoxwall(render + "--frames 1 --sink-deadline 0"),
                     "voxwall: --sink-deadline must be a positive number of seconds");
}

// The orientation goes from the file through `compress` into the .vwz and back out of
// `decompress`; `info` prints it; `--orientation` overrides it; `--view` names the camera.
TEST(Cli, OrientationIsPrintedKeptAndOverridden) {
  test::TempDir dir;
  codec::Volume v = codec::Volume::allocate({6, 5, 4}, codec::ScalarType::UInt8, {0.5, 1, 2});
  for (std::size_t i = 0; i < v.data.size(); ++i) v.data[i] = std::byte(i % 200);
  v.computeRange();
  v.orientation.direction = codec::parseOrientationLetters("RAS");
  v.orientation.origin = {-90, 126, -72};
  codec::writeVolume(v, dir.path("ras.nii"));
  const CliRun info = runVoxwall("info " + dir.path("ras.nii"));
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("orientation RAS"), std::string::npos) << info.out;
  // The voxel-to-patient matrix in LPS: x steps 0.5 mm to the right (-x), y 1 mm anterior.
  EXPECT_NE(info.out.find("   -0.5000     0.0000     0.0000     -90.0000"), std::string::npos)
      << info.out;

  ASSERT_EQ(runVoxwall("compress " + dir.path("ras.nii") + " -q -o " + dir.path("ras.vwz")).status,
            0);
  const CliRun vwz = runVoxwall("info " + dir.path("ras.vwz"));
  EXPECT_NE(vwz.out.find("orientation RAS"), std::string::npos) << vwz.out;
  EXPECT_NE(vwz.out.find(".vwz version 2"), std::string::npos) << vwz.out;
  ASSERT_EQ(runVoxwall("decompress " + dir.path("ras.vwz") + " -o " + dir.path("back.nrrd")).status,
            0);
  const codec::Volume back = codec::readVolume(dir.path("back.nrrd"));
  EXPECT_EQ(codec::orientationLetters(back.orientation.direction), "RAS");
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(back.orientation.origin[i], v.orientation.origin[i], 1e-9);
  EXPECT_EQ(back.data, v.data);

  // Overridden for a file, and for raw input that has none.
  const CliRun over = runVoxwall("compress " + dir.path("ras.nii") + " --orientation lpi -q -o " +
                                 dir.path("lpi.vwz"));
  ASSERT_EQ(over.status, 0) << over.out;
  EXPECT_NE(runVoxwall("info " + dir.path("lpi.vwz")).out.find("orientation LPI"),
            std::string::npos);
  codec::writeVolume(v, dir.path("v.raw"));
  EXPECT_NE(runVoxwall("info " + dir.path("v.raw") + " --dims 6,5,4").out.find("orientation LPS"),
            std::string::npos);
  EXPECT_NE(runVoxwall("info " + dir.path("v.raw") + " --dims 6,5,4 --orientation AIR")
                .out.find("orientation AIR"),
            std::string::npos);
  expectOneLineError(runVoxwall("info " + dir.path("ras.nii") + " --orientation RAR"),
                     "voxwall: orientation 'RAR' is not three letters");

  const CliRun anterior =
      runVoxwall("render " + dir.path("ras.vwz") + " --view anterior --size 16x16 --out " +
                 dir.path("f") + " -q");
  EXPECT_EQ(anterior.status, 0) << anterior.out;
  expectOneLineError(runVoxwall("render " + dir.path("ras.vwz") + " --view front --size 16x16 -q"),
                     "voxwall: --view: 'front' is not one of anterior, posterior, left, right, "
                     "superior, inferior");
  const CliRun both =
      runVoxwall("render " + dir.path("ras.vwz") + " --view left --camera 0,0 --size 16x16 -q");
  EXPECT_NE(both.status, 0);
  EXPECT_NE(both.out.find("excludes"), std::string::npos) << both.out;
}
