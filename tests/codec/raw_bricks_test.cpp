#include <gtest/gtest.h>

#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/core/errors.hpp>

using namespace voxwall;
using namespace voxwall::codec;

namespace {

Volume noise(ScalarType type, glm::ivec3 dims, unsigned seed) {
  Volume v = Volume::allocate(dims, type);
  std::uint32_t s = seed;
  dispatchScalar(type, [&](auto t) {
    using T = decltype(t);
    for (auto& x : v.as<T>()) {
      s = s * 1664525u + 1013904223u;
      if constexpr (std::is_same_v<T, float>)
        x = float(s >> 8) / 65536.0f - 100.0f;
      else
        x = T(s >> 16);
    }
  });
  v.computeRange();
  return v;
}

}  // namespace

class RawCodecRoundTrip : public ::testing::TestWithParam<std::tuple<ScalarType, int>> {};

TEST_P(RawCodecRoundTrip, EveryVoxelSurvivesAtOddSizes) {
  const auto [type, brick] = GetParam();
  for (glm::ivec3 dims : {glm::ivec3(1, 1, 1), glm::ivec3(13, 7, 5), glm::ivec3(17, 16, 33)}) {
    const Volume v = noise(type, dims, 7);
    Progress quiet;
    const auto c = rawbricks::encode(v, {brick}, quiet);
    const Volume back = rawbricks::decode(c.info, c.view());
    EXPECT_EQ(back.data, v.data) << dims.x << "x" << dims.y << "x" << dims.z;
    EXPECT_TRUE(std::isinf(psnr(v, back)));
    // The view agrees with the dense volume everywhere, and clamps outside.
    dispatchScalar(type, [&](auto t) {
      using T = decltype(t);
      const rawbricks::Layout layout(c.info, c.view());
      const auto view = layout.view<T>();
      for (int z = 0; z < dims.z; ++z)
        for (int y = 0; y < dims.y; ++y)
          for (int x = 0; x < dims.x; ++x)
            ASSERT_EQ(view.voxel(x, y, z), float(v.as<T>()[v.index(x, y, z)]));
      EXPECT_EQ(view.voxel(-3, 0, 0), view.voxel(0, 0, 0));
      EXPECT_EQ(view.voxel(dims.x + 5, dims.y, dims.z),
                view.voxel(dims.x - 1, dims.y - 1, dims.z - 1));
    });
  }
}

INSTANTIATE_TEST_SUITE_P(TypesAndBricks, RawCodecRoundTrip,
                         ::testing::Combine(::testing::Values(ScalarType::UInt8, ScalarType::UInt16,
                                                              ScalarType::Int16,
                                                              ScalarType::Float32),
                                            ::testing::Values(4, 8)));

TEST(RawBricks, RangeGridCoversEveryTrilinearNeighbourhood) {
  const Volume v = noise(ScalarType::UInt8, {19, 10, 9}, 3);
  Progress quiet;
  const auto c = rawbricks::encode(v, {8, 4}, quiet);  // range cells independent of the brick size
  const rawbricks::Layout layout(c.info, c.view());
  const RangeGrid grid = layout.rangeGrid();
  ASSERT_EQ(grid.cells(), glm::ivec3(5, 3, 3));
  EXPECT_EQ(layout.rangeCells(), grid.cells());
  EXPECT_EQ(layout.rangeCellVoxels(), grid.cellVoxels());
  EXPECT_EQ(grid.type(), ScalarType::UInt8);
  EXPECT_EQ(grid.bytes(), 5u * 3u * 3u * 2u);  // two bytes a cell
  // Brute force: the range of each cell grown by one voxel, clamped.
  for (int cz = 0; cz < 3; ++cz)
    for (int cy = 0; cy < 3; ++cy)
      for (int cx = 0; cx < 5; ++cx) {
        float lo = 1e9f, hi = -1e9f;
        for (int z = std::max(0, cz * 4 - 1); z < std::min(9, cz * 4 + 5); ++z)
          for (int y = std::max(0, cy * 4 - 1); y < std::min(10, cy * 4 + 5); ++y)
            for (int x = std::max(0, cx * 4 - 1); x < std::min(19, cx * 4 + 5); ++x) {
              lo = std::min(lo, float(v.as<std::uint8_t>()[v.index(x, y, z)]));
              hi = std::max(hi, float(v.as<std::uint8_t>()[v.index(x, y, z)]));
            }
        const std::size_t i = std::size_t((cz * 3 + cy) * 5 + cx);
        EXPECT_EQ(grid.lo(i), lo);
        EXPECT_EQ(grid.hi(i), hi);
      }
}

TEST(RawBricks, RejectsBadBrickSizes) {
  const Volume v = noise(ScalarType::UInt8, {4, 4, 4}, 1);
  Progress quiet;
  for (int b : {0, 3, 6, 128})
    EXPECT_THROW(rawbricks::encode(v, {b}, quiet), std::invalid_argument);
  for (int r : {0, 1, 3, 128})
    EXPECT_THROW(rawbricks::encode(v, {8, r}, quiet), std::invalid_argument);
}

TEST(RawBricks, CorruptSectionsAreRefusedByName) {
  const Volume v = noise(ScalarType::UInt16, {9, 9, 9}, 1);
  Progress quiet;
  const auto good = rawbricks::encode(v, {4}, quiet);
  auto expectError = [&](CompressedVolume c, const std::string& fragment) {
    try {
      rawbricks::Layout(c.info, c.view("f.vwz"));
      ADD_FAILURE() << "accepted: " << fragment;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).rfind("f.vwz: ", 0), 0u) << e.what();
    }
  };
  auto c = good;
  c.sections[0].second[0] = std::byte{9};  // brick shift 9
  expectError(c, "params");
  c = good;
  c.sections[2].second.pop_back();
  expectError(c, "bricks");
  c = good;
  c.sections[1].second.resize(8);
  expectError(c, "ranges");
  c = good;
  c.sections.erase(c.sections.begin() + 2);
  expectError(c, "missing section 'bricks'");
  c = good;
  c.info.dims.x = 100;  // header disagrees with the payload
  expectError(c, "expected");
}

// RawView::sample (apron bricks, position clamping, per-ray corner cache) against the generic
// clamp-to-edge trilinear reference over voxel().
TEST(RawView, SampleEqualsTheTrilinearReferenceEverywhere) {
  const Volume v = noise(ScalarType::UInt16, {19, 9, 13}, 5);
  Progress quiet;
  for (int brick : {4, 8}) {
    const auto c = rawbricks::encode(v, {brick, 4}, quiet);
    const auto view = rawbricks::Layout(c.info, c.view()).view<std::uint16_t>();
    kernels::RawView<std::uint16_t>::RayCache cache;
    std::uint32_t s = 99;
    auto coordinate = [&](int dim) {
      s = s * 1664525u + 1013904223u;
      return -1.5f + float(s >> 8) / float(1 << 24) * float(dim + 2);  // also outside the volume
    };
    for (int i = 0; i < 20000; ++i) {
      const float x = coordinate(19), y = coordinate(9), z = coordinate(13);
      const float reference = kernels::trilinear(view, x, y, z);
      ASSERT_EQ(view.sample(x, y, z), reference) << x << ", " << y << ", " << z;
      // With a cache carried from sample to sample, as a ray does.
      ASSERT_EQ(view.sample(x, y, z, cache), reference) << x << ", " << y << ", " << z;
    }
  }
}
