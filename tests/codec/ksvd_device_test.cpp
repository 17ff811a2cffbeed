// The ksvd codec's two-phase device decompressor against the host decoder. Skips (reported as
// skipped, not passed) without a usable CUDA device and in builds without CUDA.
#include <gtest/gtest.h>

#include <cmath>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/ksvd_device.hpp>

using namespace voxwall;
using namespace voxwall::codec;

namespace {
// Every brick of every level of `layout`.
std::vector<ksvd::BrickRef> allBricks(const ksvd::Layout& layout) {
  std::vector<ksvd::BrickRef> out;
  for (int l = 0; l < layout.levels(); ++l) {
    const glm::ivec3 grid = layout.levelBricks(l);
    for (int z = 0; z < grid.z; ++z)
      for (int y = 0; y < grid.y; ++y)
        for (int x = 0; x < grid.x; ++x) out.push_back({l, {x, y, z}});
  }
  return out;
}
}  // namespace

TEST(KsvdDevice, TwoPhaseDecompressionMatchesTheHostDecoder) {
  std::string reason;
  if (!ksvd::deviceDecompressionAvailable(&reason)) GTEST_SKIP() << reason;
  // Every block side, two levels each, a float and an integer volume (constant bricks, blocks
  // past the edge, blocks without pairs).
  for (int side : {4, 6, 8})
    for (const Volume& v : {generateMarschnerLobb(45, ScalarType::Float32), generateMenger(3)}) {
      SCOPED_TRACE(side);
      ksvd::Params p;
      p.blockSide = side, p.atoms = 32, p.sparsity = 6, p.iterations = 3, p.levels = 2;
      Progress quiet;
      const auto c = ksvd::encode(v, p, quiet);
      const ksvd::Layout layout(c.info, c.view());
      const auto bricks = allBricks(layout);
      const std::vector<float> host = ksvd::decompressBricks(layout, bricks);
      const std::vector<float> device = ksvd::decompressBricksOnDevice(layout, bricks);
      ASSERT_EQ(host.size(), device.size());
      // The same sums in the same order; the device may fuse multiply-adds, which moves a sum
      // by a rounding of the float: integer data, rounded after the sum, then lands on the
      // neighbouring integer where the sum was within that of a half (on an H200, 1 voxel of the
      // Menger sponge at block side 8). Such voxels are counted and must stay rare.
      const float tolerance = 1e-5f * float(v.valueMax - v.valueMin);
      const bool integral = v.type != ScalarType::Float32;
      std::size_t roundedApart = 0;
      for (std::size_t i = 0; i < host.size(); ++i) {
        if (integral && std::abs(host[i] - device[i]) == 1.0f) {
          ++roundedApart;
          continue;
        }
        ASSERT_NEAR(host[i], device[i], tolerance) << "value " << i;
      }
      EXPECT_LE(roundedApart, host.size() / 10000) << roundedApart << " of " << host.size();
    }
}

TEST(KsvdDevice, WithoutADeviceItRefusesWithAReason) {
  std::string reason;
  if (ksvd::deviceDecompressionAvailable(&reason)) GTEST_SKIP() << "a device is present";
  EXPECT_FALSE(reason.empty());
  Progress quiet;
  ksvd::Params p;
  p.atoms = 8, p.iterations = 1;
  const auto c = ksvd::encode(generateMenger(2), p, quiet);
  const ksvd::Layout layout(c.info, c.view());
  const ksvd::BrickRef brick;
  try {
    (void)ksvd::decompressBricksOnDevice(layout, std::span(&brick, 1));
    ADD_FAILURE() << "decompressed without a device";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
  }
}
