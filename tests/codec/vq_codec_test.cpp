#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/core/errors.hpp>

#include "support/format_error_expect.hpp"
#include "support/sections.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::poke;
using voxwall::test::section;

namespace {

// Noise in [lo, hi] mixed with smooth regions and runs of equal bricks, so every path of the
// coder (constant bricks, predictors, escapes, duplicates) is taken.
template <class T>
Volume vqMixed(glm::ivec3 dims, int lo, int hi, unsigned seed) {
  ScalarType type = std::is_same_v<T, std::uint8_t>    ? ScalarType::UInt8
                    : std::is_same_v<T, std::uint16_t> ? ScalarType::UInt16
                                                       : ScalarType::Int16;
  Volume v = Volume::allocate(dims, type);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> any(lo, hi);
  auto data = v.as<T>();
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        int value;
        if (z < dims.z / 3)
          value = any(rng);  // noise
        else if (z < 2 * dims.z / 3)
          value = lo + (x * 7 + y * 3 + z) % std::max(1, (hi - lo + 1));  // ramps
        else
          value = ((x / 4 + y / 4) % 2) ? hi : lo;  // repeated bricks
        data[v.index(x, y, z)] = T(value);
      }
  v.computeRange();
  return v;
}

Volume encodeDecode(const Volume& v, const vq::Params& p, vq::EncodeStats* stats = nullptr) {
  Progress quiet;
  const auto c = vq::encode(v, p, quiet, stats);
  return vq::decode(c.info, c.view());
}

vq::Brick randomBrick(std::mt19937& rng, int maxValue) {
  std::uniform_int_distribution<int> d(0, maxValue);
  vq::Brick b;
  for (auto& x : b) x = std::uint16_t(d(rng));
  return b;
}

}  // namespace

struct LosslessCase {
  const char* name;
  Volume (*make)(glm::ivec3, unsigned);
  int bits;
};

class VqLossless : public ::testing::TestWithParam<std::tuple<LosslessCase, bool>> {};

TEST_P(VqLossless, EveryVoxelSurvivesAtOddSizes) {
  const auto& [c, compressed] = GetParam();
  for (glm::ivec3 dims :
       {glm::ivec3(1, 1, 1), glm::ivec3(13, 7, 5), glm::ivec3(17, 16, 33), glm::ivec3(30, 9, 12)}) {
    const Volume v = c.make(dims, 11);
    if (v.voxelCount() > 100) {
      ASSERT_EQ(vq::bitDepth(v), c.bits);
    }
    vq::Params p;
    p.compressedCodebook = compressed;
    Progress quiet;
    vq::EncodeStats stats;
    const auto enc = vq::encode(v, p, quiet, &stats);
    const Volume back = vq::decode(enc.info, enc.view());
    EXPECT_EQ(back.data, v.data) << c.name << " " << dims.x << "x" << dims.y << "x" << dims.z;
    EXPECT_TRUE(std::isinf(stats.psnr));
    EXPECT_EQ(stats.codewords, stats.uniqueBricks);
    // The view answers every voxel like the dense volume, and clamps outside it.
    const vq::Layout layout(enc.info, enc.view());
    const auto view = layout.view();
    for (int z = -1; z <= dims.z; ++z)
      for (int y = -1; y <= dims.y; ++y)
        for (int x = -1; x <= dims.x; ++x) {
          const int cx = std::clamp(x, 0, dims.x - 1), cy = std::clamp(y, 0, dims.y - 1),
                    cz = std::clamp(z, 0, dims.z - 1);
          ASSERT_EQ(view.voxel(x, y, z), float(v.valueAt(v.index(cx, cy, cz))))
              << c.name << " at " << x << "," << y << "," << z;
        }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Depths, VqLossless,
    ::testing::Combine(
        ::testing::Values(
            LosslessCase{
                "uint8",
                [](glm::ivec3 d, unsigned s) { return vqMixed<std::uint8_t>(d, 0, 255, s); }, 8},
            LosslessCase{
                "uint16 12-bit",
                [](glm::ivec3 d, unsigned s) { return vqMixed<std::uint16_t>(d, 0, 4095, s); }, 12},
            LosslessCase{
                "uint16 16-bit",
                [](glm::ivec3 d, unsigned s) { return vqMixed<std::uint16_t>(d, 0, 65535, s); },
                16},
            LosslessCase{
                "int16 CT",
                [](glm::ivec3 d, unsigned s) { return vqMixed<std::int16_t>(d, -1024, 3071, s); },
                12},
            LosslessCase{
                "int16 full",
                [](glm::ivec3 d, unsigned s) { return vqMixed<std::int16_t>(d, -32768, 32767, s); },
                16}),
        ::testing::Bool()));

TEST(VqCodec, EqualBricksAreStoredOnce) {
  Volume v = Volume::allocate({32, 32, 32}, ScalarType::UInt8);
  vq::EncodeStats stats;
  EXPECT_EQ(encodeDecode(v, {}, &stats).data, v.data);
  EXPECT_EQ(stats.bricks, 512u);
  EXPECT_EQ(stats.uniqueBricks, 1u);
  // A checkerboard of two bricks.
  for (int z = 0; z < 32; ++z)
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x)
        v.as<std::uint8_t>()[v.index(x, y, z)] = ((x / 4 + y / 4 + z / 4) % 2) ? 200 : 3;
  v.computeRange();
  EXPECT_EQ(encodeDecode(v, {}, &stats).data, v.data);
  EXPECT_EQ(stats.uniqueBricks, 2u);
}

// A lossless file deduplicates the coded bricks row by row (no brick held); a size target that
// the lossless codebook already meets deduplicates the bricks themselves. Both must write the
// same file, byte for byte, for 8- and 16-bit data and both codebook forms.
TEST(VqCodec, DeduplicatingCodesGivesTheFileDeduplicatingBricksGives) {
  voxwall::Progress quiet;
  const Volume sl = generateSheppLogan(45);
  const Volume wide = vqMixed<std::uint16_t>({40, 36, 30}, 0, 65535, 4);
  for (const Volume* v : {&sl, &wide})
    for (bool compressed : {true, false}) {
      vq::Params coded;
      coded.compressedCodebook = compressed;
      vq::Params bricks = coded;
      bricks.targetBitsPerVoxel = 64;  // above any lossless file: kept lossless
      vq::EncodeStats a, b;
      const CompressedVolume byCodes = vq::encode(*v, coded, quiet, &a);
      const CompressedVolume byBricks = vq::encode(*v, bricks, quiet, &b);
      EXPECT_EQ(a.uniqueBricks, b.uniqueBricks);
      ASSERT_EQ(byCodes.sections.size(), byBricks.sections.size());
      for (std::size_t i = 0; i < byCodes.sections.size(); ++i)
        EXPECT_EQ(byCodes.sections[i].second, byBricks.sections[i].second)
            << "section " << i << (compressed ? " compressed" : " plain");
    }
}

TEST(VqCodec, StatsAccountForEveryCodewordAndByte) {
  const Volume v = vqMixed<std::uint16_t>({40, 36, 30}, 0, 65535, 4);
  Progress quiet;
  vq::EncodeStats stats;
  const auto c = vq::encode(v, {}, quiet, &stats);
  // Noise escapes to raw values, ramps are exact for the 3D Lorenzo predictor.
  EXPECT_GT(stats.escapes, 0u);
  EXPECT_GT(stats.transformUse[3], 0u);
  const std::uint64_t coded = stats.escapes + stats.transformUse[0] + stats.transformUse[1] +
                              stats.transformUse[2] + stats.transformUse[3];
  EXPECT_LE(coded, stats.codewords);
  const vq::Layout layout(c.info, c.view());
  EXPECT_EQ(stats.codebookBytes, layout.codebookBytes());
  EXPECT_LE(stats.offsetVolumeBytes + stats.indexTableBytes + stats.codebookBytes,
            layout.dataBytes().size());
  EXPECT_EQ(stats.indexTableBytes > 0, stats.indirect);
}

TEST(VqCodec, RefusesFloatAndBadParameters) {
  Progress quiet;
  const Volume f = Volume::allocate({8, 8, 8}, ScalarType::Float32);
  EXPECT_THROW(vq::encode(f, {}, quiet), std::invalid_argument);
  const Volume u = Volume::allocate({8, 8, 8}, ScalarType::UInt8);
  vq::Params p;
  p.reduction = 0;
  EXPECT_THROW(vq::encode(u, p, quiet), std::invalid_argument);
  p.reduction = 1;
  p.targetBitsPerVoxel = -1;
  EXPECT_THROW(vq::encode(u, p, quiet), std::invalid_argument);
}

// ---- RBUC codewords ---------------------------------------------------------------------

TEST(VqRbuc, RoundTripsEveryTransformAndNeverExceedsTheEscapeSize) {
  std::mt19937 rng(5);
  for (int bits : {8, 12, 16}) {
    const int maxValue = (1 << bits) - 1;
    std::vector<vq::Brick> bricks;
    vq::Brick b{};
    bricks.push_back(b);  // all zero
    b.fill(std::uint16_t(maxValue));
    bricks.push_back(b);                                                        // all max
    for (int i = 0; i < 20; ++i) bricks.push_back(randomBrick(rng, maxValue));  // full-range noise
    for (int i = 0; i < 20; ++i) bricks.push_back(randomBrick(rng, 3));         // small noise
    b.fill(17);
    b[37] = std::uint16_t(maxValue);
    bricks.push_back(b);  // one outlier
    for (int i = 0; i < 64; ++i)
      b[i] = std::uint16_t((i & 3) * 5 + ((i >> 2) & 3) * 9 + (i >> 4) * 2);
    bricks.push_back(b);  // a plane: the Lorenzo predictors code it in 0 bits
    for (int i = 0; i < 64; ++i) b[i] = std::uint16_t(i % 2 ? maxValue : 0);
    bricks.push_back(b);  // alternating extremes
    for (const auto& brick : bricks)
      for (int t = -1; t < 4; ++t) {
        std::vector<std::uint8_t> out;
        const int used = vq::encodeCodeword(brick, bits, out, t);
        const std::size_t size = out.size();
        EXPECT_LE(size, vq::maxCodewordBytes(bits));
        out.resize(size + 8, 0);  // the readers' 8-byte reads, as in a file's padding
        EXPECT_EQ(vq::codewordLength(out.data(), size, bits, "test"), size);
        vq::Brick back;
        kernels::vqDecodeCodeword(out.data(), bits, back.data());
        ASSERT_EQ(back, brick) << "bits " << bits << " transform " << t << " used " << used;
      }
  }
}

TEST(VqRbuc, PicksTheShortestTransformAndEscapesNoise) {
  vq::Brick plane;
  for (int i = 0; i < 64; ++i)
    plane[i] = std::uint16_t(100 + (i & 3) * 5 + ((i >> 2) & 3) * 9 + (i >> 4) * 2);
  std::vector<std::uint8_t> best, plain;
  const int t = vq::encodeCodeword(plane, 12, best);
  vq::encodeCodeword(plane, 12, plain, 0);
  EXPECT_EQ(t, 3);  // the 3D Lorenzo predictor is exact on a plane
  EXPECT_LT(best.size(), plain.size());
  std::mt19937 rng(1);
  std::vector<std::uint8_t> noise;
  EXPECT_EQ(vq::encodeCodeword(randomBrick(rng, 65535), 16, noise), kernels::kVqEscape);
  EXPECT_EQ(noise.size(), vq::maxCodewordBytes(16));
  vq::Brick constant;
  constant.fill(9);
  std::vector<std::uint8_t> c;
  EXPECT_EQ(vq::encodeCodeword(constant, 8, c), -1);
  EXPECT_EQ(c.size(), 2u);  // min and max only
}

TEST(VqRbuc, MalformedCodewordsAreRefused) {
  std::vector<std::uint8_t> w = {10, 5};  // min 10 above max 5
  w.resize(40, 0);
  EXPECT_THROW(vq::codewordLength(w.data(), 2, 8, "f"), FormatError);
  w = {1, 5, 6};  // c2 = 6 bits: more than any c1 needs
  w.resize(40, 0);
  EXPECT_THROW(vq::codewordLength(w.data(), 3, 8, "f"), FormatError);
  w = {1, 5, 1, 0xFF};  // c2 = 1 byte of c1 values all 1: 8 more bytes, only 4 given
  w.resize(40, 0);
  EXPECT_THROW(vq::codewordLength(w.data(), 4, 8, "f"), FormatError);
  EXPECT_EQ(vq::codewordLength(w.data(), 12, 8, "f"), 12u);
  w = {1, 5, 255};  // an escape whose raw bytes are missing
  w.resize(80, 0);
  EXPECT_THROW(vq::codewordLength(w.data(), 60, 8, "f"), FormatError);
}

TEST(VqMapping, DirectOrIndirectFollowsTheSizeFormula) {
  // N = 1000 entries, M = 10 codewords (a = 4 bits), 1000-byte codebook (b = 10 bits):
  // direct 1250 bytes, indirect 500 + 13 = 513 bytes.
  EXPECT_TRUE(vq::chooseIndirect(1000, 10, 1000));
  // N = 10 entries, M = 10 codewords, 40-byte codebook (b = 6): direct 8 bytes; indirect
  // ceil(40 / 8) + ceil(60 / 8) = 5 + 8 = 13 bytes.
  EXPECT_FALSE(vq::chooseIndirect(10, 10, 40));
  EXPECT_EQ(vq::bitsFor(0), 1);
  EXPECT_EQ(vq::bitsFor(1), 1);
  EXPECT_EQ(vq::bitsFor(255), 8);
  EXPECT_EQ(vq::bitsFor(256), 9);
  // The encoder writes what the formula picks.
  const Volume v = generateMarschnerLobb(40);
  Progress quiet;
  vq::EncodeStats stats;
  const auto c = vq::encode(v, {}, quiet, &stats);
  EXPECT_EQ(stats.indirect, vq::chooseIndirect(stats.bricks, stats.codewords, stats.codebookBytes));
  EXPECT_EQ(bool(vq::Layout(c.info, c.view()).flags() & vq::kIndirect), stats.indirect);
}

// ---- lossy ------------------------------------------------------------------------------

TEST(VqLossy, PsnrFallsAsTheCodebookShrinksAndIsWhatTheFileSays) {
  const Volume v = generateMarschnerLobb(48);
  double last = std::numeric_limits<double>::infinity();
  std::uint64_t lastCodewords = 0;
  for (int k : {1, 2, 4, 8, 16, 64, 256}) {
    vq::Params p;
    p.reduction = k;
    Progress quiet;
    vq::EncodeStats stats;
    const auto c = vq::encode(v, p, quiet, &stats);
    const Volume back = vq::decode(c.info, c.view());
    const double measured = psnr(v, back);
    EXPECT_DOUBLE_EQ(vq::Layout(c.info, c.view()).psnr(), measured) << "reduction " << k;
    EXPECT_DOUBLE_EQ(stats.psnr, measured);
    EXPECT_LE(measured, last) << "reduction " << k;
    if (k > 1) {
      EXPECT_LT(measured, 200.0);
      EXPECT_LT(stats.codewords, lastCodewords);
      EXPECT_GT(stats.distancesSkipped, 0u);
    }
    last = measured, lastCodewords = stats.codewords;
  }
  EXPECT_GT(last, 20.0);  // 1/256 of the bricks still resembles the signal
}

TEST(VqLossy, TargetBitsPerVoxelIsMet) {
  const Volume v = generateMarschnerLobb(48);
  for (double target : {1.0, 2.0}) {
    vq::Params p;
    p.targetBitsPerVoxel = target;
    Progress quiet;
    vq::EncodeStats stats;
    const auto c = vq::encode(v, p, quiet, &stats);
    const double bpv = 8.0 * double(c.payloadBytes()) / double(v.voxelCount());
    EXPECT_LE(bpv, target * 1.05) << target;
    EXPECT_GT(stats.reduction, 1);
  }
}

// ---- corrupt sections -------------------------------------------------------------------

namespace {
CompressedVolume small(bool compressed) {
  const Volume v = vqMixed<std::uint16_t>({13, 9, 10}, 0, 4095, 3);
  vq::Params p;
  p.compressedCodebook = compressed;
  Progress quiet;
  return vq::encode(v, p, quiet);
}
void expectVqRefused(const CompressedVolume& c, const std::string& fragment) {
  test::expectFormatError([&] { vq::Layout(c.info, c.view("bad.vwz")); }, "bad.vwz", fragment);
}
}  // namespace

TEST(VqCorrupt, BadSectionsAreRefusedWithTheirName) {
  for (bool compressed : {true, false}) {
    {
      auto c = small(compressed);
      section(c, vq::kParams).resize(20);
      expectVqRefused(c, "section 'params': truncated");
    }
    {
      auto c = small(compressed);
      poke<std::uint32_t>(section(c, vq::kParams), 0, 10);
      expectVqRefused(c, "bit depth 10");
    }
    {
      auto c = small(compressed);
      poke<std::uint32_t>(section(c, vq::kParams), 12, 0);
      expectVqRefused(c, "offset bits 0");
    }
    {
      auto c = small(compressed);
      poke<std::uint64_t>(section(c, vq::kParams), 24, 1u << 30);
      expectVqRefused(c, "codewords for");
    }
    {
      auto c = small(compressed);
      poke<std::uint64_t>(section(c, vq::kParams), 48, std::uint64_t(1) << 40);
      expectVqRefused(c, "does not fit");
    }
    {
      auto c = small(compressed);
      section(c, vq::kData).resize(section(c, vq::kData).size() / 2);
      expectVqRefused(c, "section 'data'");
    }
    {
      // Every offset entry set to all ones: names no codeword (or an address no codeword has).
      auto c = small(compressed);
      auto& d = section(c, vq::kData);
      std::uint32_t offsetBits;
      std::memcpy(&offsetBits, section(c, vq::kParams).data() + 12, 4);
      const std::size_t bytes = (std::size_t(4 * 3 * 3) * offsetBits + 7) / 8;
      for (std::size_t i = 0; i < bytes; ++i) d[i] = std::byte{0xFF};
      expectVqRefused(c, "names no codeword");
    }
    auto c = small(compressed);
    c.sections.pop_back();
    expectVqRefused(c, "missing section");
  }
  {
    // Indirect mapping (many bricks, few codewords): an index-table entry that is not its
    // codeword's start.
    Volume v = Volume::allocate({64, 64, 64}, ScalarType::UInt8);
    for (int z = 0; z < 64; ++z)
      for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x)
          v.as<std::uint8_t>()[v.index(x, y, z)] =
              std::uint8_t((x / 4 + 3 * (y / 4)) % 5 * 40 + x % 4);
    v.computeRange();
    Progress quiet;
    auto c = vq::encode(v, {}, quiet);
    const vq::Layout layout(c.info, c.view());
    ASSERT_TRUE(layout.flags() & vq::kIndirect);
    section(c, vq::kData)[layout.indexTableAt()] ^= std::byte{1};
    expectVqRefused(c, "index table entry 0");
  }
  // A codeword's header byte claiming c2 = 7.
  auto c = small(true);
  const vq::Layout layout(c.info, c.view());
  auto& d = section(c, vq::kData);
  // Find the first non-constant codeword (min != max) and corrupt its header.
  std::size_t pos = layout.codebookAt();
  const auto* p = reinterpret_cast<const std::uint8_t*>(d.data());
  for (;;) {
    const auto lo = kernels::readBits(p + pos, 0, 12), hi = kernels::readBits(p + pos, 12, 12);
    if (lo != hi) break;
    pos += 3;
  }
  d[pos + 3] = std::byte{7};
  expectVqRefused(c, "malformed codeword");
}

TEST(VqCodec, RangeGridCoversEveryTrilinearNeighbourhood) {
  const Volume v = vqMixed<std::uint8_t>({21, 18, 15}, 0, 255, 9);
  Progress quiet;
  const auto c = vq::encode(v, {}, quiet);
  const RangeGrid g = vq::Layout(c.info, c.view()).rangeGrid();
  ASSERT_EQ(g.cellVoxels(), 4);
  for (int z = 0; z < v.dims.z; ++z)
    for (int y = 0; y < v.dims.y; ++y)
      for (int x = 0; x < v.dims.x; ++x) {
        const std::size_t cell = g.cellIndex(x / 4, y / 4, z / 4);
        for (int dz = 0; dz < 2; ++dz)
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
              const double value =
                  v.valueAt(v.index(std::min(x + dx, v.dims.x - 1), std::min(y + dy, v.dims.y - 1),
                                    std::min(z + dz, v.dims.z - 1)));
              ASSERT_GE(value, g.lo(cell));
              ASSERT_LE(value, g.hi(cell));
            }
      }
}

// A series coded with one codebook: each step's view reads its offset volume from its own data
// and the codewords from the shared book, on the host and from the one buffer a device backend
// uploads (joinedBytes, the book at deviceBookAt) alike; a step without its book, or with a book
// cut short, is refused naming the section.
TEST(VqSeries, StepsReadTheSharedBookWhereverItLies) {
  test::TempDir dir;
  std::vector<SeriesSource::Step> steps;
  std::vector<Volume> volumes;
  for (int k = 0; k < 3; ++k) {
    volumes.push_back(vqMixed<std::uint16_t>({13, 9, 10}, 0, 4095, 3 + k % 2));
    // (std::string("s"): gcc 12 warns falsely of overlapping copies in "s" + std::string.)
    const std::string file = dir.path(std::string("s") + std::to_string(k) + ".nrrd");
    writeVolume(volumes.back(), file);
    steps.push_back({file, file, 0, SeriesSource::Kind::File});
  }
  const SeriesSource series(steps, {});
  Progress quiet;
  const CompressedSeries coded = vq::encodeSeries(series, {}, quiet);
  // The book is shared (so are the params: lossless, every step's are alike).
  EXPECT_TRUE(std::any_of(coded.shared.begin(), coded.shared.end(),
                          [](const auto& s) { return s.first == vq::kBook; }));
  for (int k = 0; k < 3; ++k) {
    const CompressedVolume step = coded.step(k);
    const vq::Layout layout(step.info, step.view());
    ASSERT_TRUE(layout.sharedBook());
    const Volume host = decodeBricks(layout.view(), step.info.type, step.info.spacing);
    EXPECT_TRUE(host.data == volumes[std::size_t(k)].data) << "step " << k;
    const std::vector<std::byte> joined = layout.joinedBytes();
    EXPECT_EQ(layout.deviceBookAt() % 64, 0u);
    const Volume device =
        decodeBricks(layout.view(joined.data()), step.info.type, step.info.spacing);
    EXPECT_TRUE(device.data == host.data) << "step " << k;
  }
  CompressedVolume bookless = coded.step(0);
  std::erase_if(bookless.sections, [](const auto& s) { return s.first == vq::kBook; });
  try {
    vq::Layout(bookless.info, bookless.view("bad.vwz"));
    ADD_FAILURE() << "a step without its book was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("book"), std::string::npos) << e.what();
  }
  CompressedVolume cut = coded.step(1);
  section(cut, vq::kBook).resize(64);
  try {
    vq::Layout(cut.info, cut.view("bad.vwz"));
    ADD_FAILURE() << "a book cut short was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("section 'book'"), std::string::npos) << e.what();
  }
}

// A shared book may hold up to 2^32 codewords, but never more than its bytes can: a count past
// them is refused before anything is allocated for it (the walk once reserved 8 bytes for each
// codeword the header claimed, 32 GiB for a fuzzed count). Steps of noise: every brick its own
// codeword, so the book is mapped directly (an indirect one's index table would not fit first).
TEST(VqSeries, ACodewordCountPastTheSharedBookIsRefusedBeforeAnythingIsReserved) {
  test::TempDir dir;
  std::vector<SeriesSource::Step> steps;
  std::mt19937 rng(5);
  for (int k = 0; k < 2; ++k) {
    Volume v = Volume::allocate({16, 16, 16}, ScalarType::UInt8);
    for (auto& value : v.as<std::uint8_t>()) value = std::uint8_t(rng());
    v.computeRange();
    const std::string file = dir.path(std::string("n") + std::to_string(k) + ".nrrd");
    writeVolume(v, file);
    steps.push_back({file, file, 0, SeriesSource::Kind::File});
  }
  Progress quiet;
  const CompressedSeries coded = vq::encodeSeries(SeriesSource(steps, {}), {}, quiet);
  CompressedVolume many = coded.step(1);
  {
    const vq::Layout layout(many.info, many.view());
    ASSERT_TRUE(layout.sharedBook());
    ASSERT_FALSE(layout.flags() & vq::kIndirect);
  }
  poke<std::uint64_t>(section(many, vq::kParams), 24, (std::uint64_t(1) << 32) - 1);
  test::expectFormatError([&] { vq::Layout(many.info, many.view("bad.vwz")); }, "bad.vwz",
                          "more codewords than the codebook's");
}
