// Random access into the raw codec's bricked voxels, on the host or on a device.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <voxwall/codec/kernels/trilinear.hpp>

namespace voxwall::codec::kernels {

// Bricks of (1 << brickShift)^3 voxels, bricks x fastest, voxels in a brick x fastest; border
// bricks are padded. `bricks` points into host or device memory and is not owned.
template <class T>
struct RawView {
  const T* bricks = nullptr;
  int dimX = 0, dimY = 0, dimZ = 0;
  int bricksX = 0, bricksY = 0;
  int brickShift = 3;

  VOXWALL_HD_INLINE float voxel(int x, int y, int z) const {
    x = clampIndex(x, dimX), y = clampIndex(y, dimY), z = clampIndex(z, dimZ);
    const int mask = (1 << brickShift) - 1;
    const std::size_t brick =
        (std::size_t(z >> brickShift) * std::size_t(bricksY) + std::size_t(y >> brickShift)) *
            std::size_t(bricksX) +
        std::size_t(x >> brickShift);
    const std::size_t inBrick =
        (((std::size_t(z & mask) << brickShift) | std::size_t(y & mask)) << brickShift) |
        std::size_t(x & mask);
    return float(bricks[(brick << (3 * brickShift)) | inBrick]);
  }
  VOXWALL_HD_INLINE float sample(float x, float y, float z) const {
    return trilinear(*this, x, y, z);
  }
};

static_assert(std::is_trivially_copyable_v<RawView<std::uint8_t>>);
static_assert(std::is_trivially_copyable_v<RawView<float>>);

}  // namespace voxwall::codec::kernels
