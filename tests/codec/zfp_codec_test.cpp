#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <variant>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/zfp_codec.hpp>
#include <voxwall/core/errors.hpp>

#include "support/sections.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::poke;
using voxwall::test::section;

namespace {

// One volume of every scalar type, of sizes that leave partial bricks at the far faces.
std::vector<Volume> everyType() {
  std::vector<Volume> out;
  out.push_back(generateSheppLogan(37));
  out.push_back(generateMarschnerLobb(21, ScalarType::UInt16));
  out.push_back(generateSheppLogan(19, ScalarType::Int16));
  out.push_back(generateMarschnerLobb(23, ScalarType::Float32));
  return out;
}

Volume roundTrip(const Volume& v, const zfp::Params& p, zfp::EncodeStats* stats = nullptr,
                 CompressedVolume* coded = nullptr) {
  Progress quiet;
  CompressedVolume c = zfp::encode(v, p, quiet, stats);
  Volume out = zfp::decode(c.info, c.view());
  if (coded) *coded = std::move(c);
  return out;
}

// The index's entries (params offset 20 holds their width; 0 in files with a u32 each), as
// u32s: bit 31 the stored flag, below it the brick's offset in its row. `rows`: the u64 row
// starts before them, one more than the rows.
int entryBits(const CompressedVolume& c) {
  std::uint32_t bits;
  std::memcpy(&bits, section(const_cast<CompressedVolume&>(c), zfp::kParams).data() + 20, 4);
  return bits == 0 ? 32 : int(bits);
}
std::vector<std::uint32_t> entries(CompressedVolume& c, std::size_t rows) {
  const auto& index = section(c, zfp::kIndex);
  const int bits = entryBits(c);
  std::vector<std::uint32_t> out;
  for (std::uint64_t at = 8 * rows * 8; at + std::uint64_t(bits) <= 8 * index.size();
       at += std::uint64_t(bits)) {
    std::uint64_t e = 0;
    for (int b = 0; b < bits; ++b)
      e |= std::uint64_t((std::to_integer<unsigned>(index[(at + b) / 8]) >> ((at + b) % 8)) & 1)
           << b;
    out.push_back(std::uint32_t(e & ((std::uint64_t(1) << (bits - 1)) - 1)) |
                  ((e >> (bits - 1)) & 1 ? 1u << 31 : 0u));
  }
  return out;
}
// Writes `e` back at `bits` bits each (the params' width set to match; 0 for u32 entries).
void setEntries(CompressedVolume& c, std::size_t rows, const std::vector<std::uint32_t>& e,
                int bits = 0) {
  if (bits == 0) bits = entryBits(c);
  auto& index = section(c, zfp::kIndex);
  index.resize(8 * rows);
  index.resize(8 * rows + (e.size() * std::size_t(bits) + 7) / 8, std::byte{0});
  for (std::size_t i = 0; i < e.size(); ++i) {
    const std::uint64_t v =
        (e[i] & ~(1u << 31)) | (e[i] >> 31 ? std::uint64_t(1) << (bits - 1) : 0);
    for (int b = 0; b < bits; ++b) {
      const std::uint64_t at = 8 * 8 * rows + i * std::size_t(bits) + std::size_t(b);
      if ((v >> b) & 1) index[at / 8] |= std::byte(1u << (at % 8));
    }
  }
  poke(section(c, zfp::kParams), 20, std::uint32_t(bits == 32 ? 0 : bits));
}

double maxError(const Volume& a, const Volume& b) {
  double e = 0;
  for (std::size_t i = 0; i < a.voxelCount(); ++i)
    e = std::max(e, std::abs(a.valueAt(i) - b.valueAt(i)));
  return e;
}

Volume noise(glm::ivec3 dims, ScalarType type, unsigned seed) {
  Volume v = Volume::allocate(dims, type);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  for (auto& b : v.data) b = std::byte(byte(rng));
  if (type == ScalarType::Float32)  // finite values: noise in [-1, 1]
    for (float& f : v.as<float>()) f = float(byte(rng)) / 127.5f - 1;
  v.computeRange();
  return v;
}

}  // namespace

TEST(ZfpCodec, FixedAccuracyHoldsItsToleranceOnEveryVoxelOfEveryType) {
  for (const Volume& v : everyType())
    for (double fraction : {0.001, 0.02, 0.2}) {
      zfp::Params p;
      p.tolerance = fraction * (v.valueMax - v.valueMin);
      zfp::EncodeStats s;
      const Volume d = roundTrip(v, p, &s);
      ASSERT_EQ(d.dims, v.dims);
      ASSERT_EQ(d.type, v.type);
      const std::string label = std::string(scalarName(v.type)) + " at " + std::to_string(fraction);
      // Integers are rounded after zfp's error: half a unit more.
      const double bound = p.tolerance + (v.type == ScalarType::Float32 ? 0 : 0.5);
      const double e = maxError(v, d);
      EXPECT_LE(e, bound) << label;
      EXPECT_NEAR(s.maxError, e, 1e-6 * (1 + e)) << label << ": the report's largest error";
      const double measured = psnr(v, d);
      if (std::isinf(measured))
        EXPECT_TRUE(std::isinf(s.psnr)) << label;
      else
        EXPECT_NEAR(s.psnr, measured, 1e-6) << label;
    }
}

TEST(ZfpCodec, LosslessIsBitForBitOnEveryType) {
  for (const Volume& v : everyType()) {
    zfp::Params p;
    p.mode = zfp::Mode::Reversible;
    zfp::EncodeStats s;
    const Volume d = roundTrip(v, p, &s);
    EXPECT_EQ(d.data, v.data) << scalarName(v.type);
    EXPECT_TRUE(std::isinf(s.psnr));
    EXPECT_EQ(s.maxError, 0);
  }
}

TEST(ZfpCodec, MorePrecisionOrRateGivesABetterPicture) {
  const Volume v = generateMarschnerLobb(40, ScalarType::Float32);
  double last = 0;
  for (int planes : {6, 10, 16}) {
    zfp::Params p;
    p.mode = zfp::Mode::Precision, p.precision = planes;
    zfp::EncodeStats s;
    roundTrip(v, p, &s);
    EXPECT_GT(s.psnr, last) << planes << " planes";
    last = s.psnr;
  }
  last = 0;
  for (double rate : {1.0, 4.0, 12.0}) {
    zfp::Params p;
    p.mode = zfp::Mode::Rate, p.rate = rate;
    zfp::EncodeStats s;
    roundTrip(v, p, &s);
    EXPECT_GT(s.psnr, last) << rate << " bits";
    last = s.psnr;
    // Every block of 64 voxels takes the same bits: the stream is the rate plus the padding of
    // the partial blocks at the far faces (40 = 2 bricks of 16 and one of 8: no partial block).
    EXPECT_NEAR(double(s.streamBytes) * 8 / double(v.voxelCount()), rate, 0.01 * rate);
  }
}

TEST(ZfpCodec, NoiseIsNeverLargerThanItsVoxels) {
  for (ScalarType type : {ScalarType::UInt8, ScalarType::UInt16, ScalarType::Float32}) {
    const Volume v = noise({35, 33, 18}, type, 7);
    for (zfp::Mode mode : {zfp::Mode::Reversible, zfp::Mode::Accuracy}) {
      zfp::Params p;
      p.mode = mode;
      p.tolerance = 1e-6;  // finer than the data: zfp would expand every brick
      zfp::EncodeStats s;
      CompressedVolume c;
      const Volume d = roundTrip(v, p, &s, &c);
      const std::uint64_t raw = v.voxelCount() * scalarBytes(type);
      // Bricks lie back to back: the stream is padded to one whole word at its end.
      EXPECT_LE(s.streamBytes, raw + 8) << scalarName(type);
      EXPECT_LE(c.payloadBytes(), raw + 8 + s.indexBytes + 72) << scalarName(type);
      EXPECT_GT(s.storedBricks, 0u) << scalarName(type);
      EXPECT_LE(maxError(v, d), 1e-6) << scalarName(type);
    }
  }
}

TEST(ZfpCodec, ASizeTargetIsMetOrRefusedWithWhatIsReachable) {
  const Volume v = generateMarschnerLobb(48, ScalarType::Float32);
  for (double target : {0.5, 1.0, 3.0}) {
    zfp::Params p;
    p.targetBitsPerVoxel = target;
    zfp::EncodeStats s;
    roundTrip(v, p, &s);
    // Every brick of a volume this small is in the sample: the file fits exactly.
    EXPECT_LE(s.bitsPerVoxel, target + 0.01) << target;
    EXPECT_GT(s.searchSteps, 0);
  }
  zfp::Params tiny;
  tiny.targetBitsPerVoxel = 0.001;
  Progress quiet;
  try {
    zfp::encode(v, tiny, quiet);
    FAIL() << "a target below the index's own size was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("is below the smallest zfp file"), std::string::npos)
        << e.what();
  }
  // A target the lossless file meets gives the lossless file.
  zfp::Params roomy;
  roomy.targetBitsPerVoxel = 40;
  zfp::EncodeStats s;
  const Volume d = roundTrip(v, roomy, &s);
  EXPECT_EQ(s.mode, zfp::Mode::Reversible);
  EXPECT_EQ(d.data, v.data);
}

TEST(ZfpCodec, RefusesNonFiniteFloatsAndBadSettings) {
  Volume v = generateMarschnerLobb(9, ScalarType::Float32);
  v.as<float>()[5] = std::nanf("");
  Progress quiet;
  EXPECT_THROW(zfp::encode(v, {}, quiet), std::invalid_argument);
  const Volume ok = generateSheppLogan(9);
  zfp::Params p;
  p.mode = zfp::Mode::Precision, p.precision = 0;
  EXPECT_THROW(zfp::encode(ok, p, quiet), std::invalid_argument);
  p.mode = zfp::Mode::Rate, p.rate = 0.1;
  EXPECT_THROW(zfp::encode(ok, p, quiet), std::invalid_argument);
}

TEST(ZfpCodec, CorruptSectionsAreRefusedWithOneError) {
  Progress quiet;
  const CompressedVolume good = zfp::encode(generateSheppLogan(37), {}, quiet);
  auto refused = [&](const char* what, auto edit) {
    CompressedVolume c = good;
    edit(c);
    EXPECT_THROW(zfp::decode(c.info, c.view()), FormatError) << what;
  };
  refused("mode 9", [](CompressedVolume& c) { poke(section(c, zfp::kParams), 0, 9u); });
  refused("parameters of another mode",
          [](CompressedVolume& c) { poke(section(c, zfp::kParams), 8, 0u); });
  refused("params cut short", [](CompressedVolume& c) { section(c, zfp::kParams).resize(40); });
  refused("a value range that is not finite",
          [](CompressedVolume& c) { poke(section(c, zfp::kParams), 56, std::nan("")); });
  // 37^3 voxels: 3 x 3 x 3 bricks, 9 rows along x; the index is 10 u64 row offsets, then an
  // entry per brick.
  refused("a row past the stream",
          [](CompressedVolume& c) { poke(section(c, zfp::kIndex), 8, std::uint64_t(1) << 40); });
  refused("rows out of order", [](CompressedVolume& c) {
    std::uint64_t second;
    std::memcpy(&second, section(c, zfp::kIndex).data() + 16, 8);
    poke(section(c, zfp::kIndex), 8, second + 1);
  });
  const int width = entryBits(good);
  refused("a brick that ends before it starts", [&](CompressedVolume& c) {
    auto e = entries(c, 10);
    e[1] = (1u << (width - 1)) - 1;  // the farthest offset the width holds: past brick 2's
    setEntries(c, 10, e);
  });
  refused("a first brick that does not start its row", [](CompressedVolume& c) {
    auto e = entries(c, 10);
    e[0] = 1;
    setEntries(c, 10, e);
  });
  refused("an index one byte short", [](CompressedVolume& c) {
    section(c, zfp::kIndex).resize(section(c, zfp::kIndex).size() - 1);
  });
  refused("index entries of 1 bit",
          [](CompressedVolume& c) { poke(section(c, zfp::kParams), 20, std::uint32_t(1)); });
  refused("index entries of 33 bits",
          [](CompressedVolume& c) { poke(section(c, zfp::kParams), 20, std::uint32_t(33)); });
  refused("a brick stream cut short", [](CompressedVolume& c) {
    section(c, zfp::kStream).resize(section(c, zfp::kStream).size() - 8);
  });
  refused("a brick marked stored with a zfp stream's length", [](CompressedVolume& c) {
    auto e = entries(c, 10);
    e[0] |= 1u << 31;
    setEntries(c, 10, e);
  });
  refused("bricks of no bits in an empty stream", [](CompressedVolume& c) {
    auto& index = section(c, zfp::kIndex);
    std::fill(index.begin(), index.end(), std::byte{0});
    section(c, zfp::kStream).clear();
  });
  refused("a missing stream", [](CompressedVolume& c) {
    std::erase_if(c.sections, [](const auto& s) { return s.first == zfp::kStream; });
  });
}

// The index's entries are as wide as the largest offset in a row needs (plus the stored flag),
// not a u32 each; a file written before the width was stored (0 in its place, a u32 per entry)
// decodes to the same voxels.
TEST(ZfpCodec, IndexEntriesArePackedAndFilesWithU32EntriesStillRead) {
  for (const Volume& v : everyType()) {
    zfp::EncodeStats s;
    CompressedVolume c;
    const Volume d = roundTrip(v, {}, &s, &c);
    const std::size_t rows = std::size_t((v.dims.y + 15) / 16) * std::size_t((v.dims.z + 15) / 16);
    const int bits = entryBits(c);
    EXPECT_LT(bits, 32) << scalarName(v.type);
    EXPECT_EQ(s.indexBytes, 8 * (rows + 1) + (s.bricks * std::uint64_t(bits) + 7) / 8);
    EXPECT_EQ(section(c, zfp::kIndex).size(), s.indexBytes);
    const auto e = entries(c, rows + 1);
    ASSERT_EQ(e.size(), s.bricks) << scalarName(v.type);
    CompressedVolume old = c;
    setEntries(old, rows + 1, e, 32);
    EXPECT_EQ(section(old, zfp::kIndex).size(), 8 * (rows + 1) + 4 * s.bricks);
    EXPECT_TRUE(zfp::decode(old.info, old.view()).data == d.data) << scalarName(v.type);
  }
}

TEST(ZfpCodec, GarbageStreamBytesDecodeInsideTheValueRange) {
  Progress quiet;
  const Volume v = generateMarschnerLobb(33, ScalarType::Float32);
  CompressedVolume c = zfp::encode(v, {}, quiet);
  std::mt19937 rng(3);
  for (auto& b : section(c, zfp::kStream)) b = std::byte(rng());
  const Volume d = zfp::decode(c.info, c.view());
  for (float f : d.as<float>()) {
    ASSERT_TRUE(std::isfinite(f));
    ASSERT_GE(f, float(v.valueMin));
    ASSERT_LE(f, float(v.valueMax));
  }
}

// What a device backend samples (raw's view of the volume decoded once) is the volume the host
// view samples: checked here on the host, with the "device copy" in host memory.
TEST(ZfpCodec, TheDeviceViewSamplesTheVolumeTheHostViewSamples) {
  Progress quiet;
  for (const Volume& v : everyType()) {
    zfp::Params p;
    p.tolerance = 0.05 * (v.valueMax - v.valueMin);
    const CompressedVolume c = zfp::encode(v, p, quiet);
    const SectionSet sections = c.view();
    const auto payload = zfp::ZfpCodecEntry::instance().open(c.info, sections);
    const auto bytes = payload->bytes();
    ASSERT_FALSE(bytes.empty());
    const AnyView host = payload->view(nullptr);
    const AnyView device = payload->deviceView(bytes.data(), {});
    ASSERT_TRUE(std::holds_alternative<kernels::ZfpView>(host));
    ASSERT_FALSE(std::holds_alternative<kernels::ZfpView>(device)) << "libzfp cannot run there";
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> x(-1, float(v.dims.x)), y(-1, float(v.dims.y)),
        z(-1, float(v.dims.z));
    for (int i = 0; i < 500; ++i) {
      const float px = x(rng), py = y(rng), pz = z(rng);
      const float a = std::visit([&](const auto& view) { return view.sample(px, py, pz); }, host);
      const float b = std::visit([&](const auto& view) { return view.sample(px, py, pz); }, device);
      ASSERT_NEAR(a, b, 1e-4f * float(1 + std::abs(v.valueMax))) << scalarName(v.type);
    }
  }
}
