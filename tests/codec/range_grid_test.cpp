// RangeGrid holds each cell's range in the volume's own type, rounded outwards.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>
#include <voxwall/codec/range_grid.hpp>

using namespace voxwall::codec;

namespace {

std::vector<float> los(const RangeGrid& g) {
  std::vector<float> out;
  g.forEach([&](std::size_t c, float lo, float) {
    EXPECT_EQ(c, out.size());
    out.push_back(lo);
  });
  return out;
}
std::vector<float> his(const RangeGrid& g) {
  std::vector<float> out;
  g.forEach([&](std::size_t, float, float hi) { out.push_back(hi); });
  return out;
}
RangeGrid filled(ScalarType type) {
  RangeGrid g(4, {4, 1, 1}, type);
  const float lo[] = {0.0f, 12.4f, -3.0f, std::nanf("")};
  const float hi[] = {255.0f, 12.6f, 300.0f, 7.0f};
  for (std::size_t c = 0; c < 4; ++c) g.set(c, lo[c], hi[c]);
  return g;
}

}  // namespace

TEST(RangeGrid, HoldsTheVolumesTypeRoundedOutwards) {
  const RangeGrid u8 = filled(ScalarType::UInt8);
  EXPECT_EQ(u8.bytes(), 8u);  // 2 bytes a cell
  EXPECT_EQ(u8.cellCount(), 4u);
  EXPECT_EQ(los(u8), (std::vector<float>{0, 12, 0, 0}));  // floor, clamped; NaN widens
  EXPECT_EQ(his(u8), (std::vector<float>{255, 13, 255, 7}));
  const RangeGrid s16 = filled(ScalarType::Int16);
  EXPECT_EQ(los(s16), (std::vector<float>{0, 12, -3, -32768}));
  EXPECT_EQ(his(s16), (std::vector<float>{255, 13, 300, 7}));
  const RangeGrid f32 = filled(ScalarType::Float32);
  EXPECT_EQ(f32.bytes(), 32u);
  EXPECT_EQ(f32.lo(1), 12.4f);  // float data keeps its ranges exactly
  EXPECT_EQ(f32.hi(2), 300.0f);
  EXPECT_TRUE(std::isnan(f32.lo(3)));
}

TEST(RangeGrid, ACellIsEmptyUntilWidenedAndThenHoldsEveryValue) {
  for (ScalarType type : {ScalarType::UInt8, ScalarType::UInt16, ScalarType::Float32}) {
    RangeGrid g(2, {2, 2, 1}, type);
    EXPECT_GT(g.lo(3), g.hi(3));  // empty: nothing was added
    g.widen(3, 40.5f);
    g.widen(3, 7.0f);
    g.widen(3, 19.0f);
    const bool integer = type != ScalarType::Float32;
    EXPECT_EQ(g.lo(3), 7.0f);
    EXPECT_EQ(g.hi(3), integer ? 41.0f : 40.5f);
    EXPECT_EQ(g.cellIndex(1, 1, 0), 3u);
    EXPECT_GT(g.lo(0), g.hi(0));  // the others untouched
  }
  RangeGrid f(2, {1, 1, 1}, ScalarType::Float32);
  f.widen(0, 1.0f);
  f.widen(0, std::nanf(""));
  EXPECT_TRUE(std::isnan(f.lo(0)) && std::isnan(f.hi(0)));  // unknown stays the whole range
  f.widen(0, 2.0f);
  EXPECT_TRUE(std::isnan(f.lo(0)));
}

// Packed, the grid gives every cell's range as before, one chunk at a time or several at once,
// in less memory; random access is refused.
TEST(RangeGrid, PackedRangesReadBackExactly) {
  for (ScalarType type : {ScalarType::UInt8, ScalarType::Int16, ScalarType::Float32}) {
    RangeGrid g(4, {300, 250, 3}, type);  // 225000 cells: four chunks, the last one short
    ASSERT_GT(g.cellCount(), 3 * RangeGrid::kChunkCells);
    for (std::size_t c = 0; c < g.cellCount(); ++c) {
      const float lo = c % 7 == 0 ? 0.0f : float((c * 37) % 90) + 0.5f;  // runs and noise
      g.set(c, lo, lo + float(c % 13));
    }
    std::vector<float> lo, hi;
    g.forEach([&](std::size_t, float l, float h) { lo.push_back(l), hi.push_back(h); });
    const std::size_t unpacked = g.bytes();
    g.pack();
    EXPECT_TRUE(g.packed());
    EXPECT_LT(g.bytes(), unpacked);
    std::size_t next = 0;
    g.forEach([&](std::size_t c, float l, float h) {
      ASSERT_EQ(c, next++);
      ASSERT_EQ(l, lo[c]);
      ASSERT_EQ(h, hi[c]);
    });
    EXPECT_EQ(next, g.cellCount());
    std::vector<std::uint8_t> seen(g.cellCount(), 0);
    std::vector<float> plo(g.cellCount()), phi(g.cellCount());
    g.forEachParallel(3, [&](std::size_t c, float l, float h) {
      ++seen[c];
      plo[c] = l, phi[c] = h;
    });
    EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), std::ptrdiff_t(g.cellCount()));
    EXPECT_EQ(plo, lo);
    EXPECT_EQ(phi, hi);
    EXPECT_THROW((void)g.lo(0), std::logic_error);
    EXPECT_THROW(g.set(0, 1, 2), std::logic_error);
  }
}
