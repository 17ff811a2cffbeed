// Random access into the raw codec's bricked voxels, on the host or on a device.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <voxwall/codec/kernels/trilinear.hpp>

namespace voxwall::codec::kernels {

// Bricks of B = 2^brickShift voxels per side, each stored with a one-voxel apron on its high
// side: (B + 1)^3 scalars holding voxels [b B, b B + B] per axis (x fastest), bricks x fastest;
// voxels past the volume's edge repeat the edge voxel. Every trilinear neighbourhood therefore
// lies inside one brick. `bricks` points into host or device memory and is not owned.
template <class T>
struct RawView {
  const T* bricks = nullptr;
  int dimX = 0, dimY = 0, dimZ = 0;
  int brickShift = 4;
  int mask = 15;                       // B - 1
  int rowStride = 17;                  // B + 1: scalars between rows of a brick
  int sliceStride = 289;               // (B + 1)^2
  std::size_t brickStrideX = 0;        // (B + 1)^3: scalars from one brick to the next along x
  std::size_t brickStrideY = 0;        // bricksX * brickStrideX
  std::size_t brickStrideZ = 0;        // bricksY * brickStrideY
  float maxX = 0, maxY = 0, maxZ = 0;  // dim - 1, as floats for clamping positions

  static RawView make(const T* bricks, int dimX, int dimY, int dimZ, int bricksX, int bricksY,
                      int brickShift) {
    RawView v;
    v.bricks = bricks;
    v.dimX = dimX, v.dimY = dimY, v.dimZ = dimZ;
    v.brickShift = brickShift;
    v.mask = (1 << brickShift) - 1;
    v.rowStride = (1 << brickShift) + 1;
    v.sliceStride = v.rowStride * v.rowStride;
    v.brickStrideX = std::size_t(v.sliceStride) * std::size_t(v.rowStride);
    v.brickStrideY = std::size_t(bricksX) * v.brickStrideX;
    v.brickStrideZ = std::size_t(bricksY) * v.brickStrideY;
    v.maxX = float(dimX - 1), v.maxY = float(dimY - 1), v.maxZ = float(dimZ - 1);
    return v;
  }

  // Address of voxel (x, y, z), 0 <= x < dimX etc., in the brick that holds it in its core.
  VOXWALL_HD_INLINE std::size_t offset(int x, int y, int z) const {
    return std::size_t(x >> brickShift) * brickStrideX +
           std::size_t(y >> brickShift) * brickStrideY +
           std::size_t(z >> brickShift) * brickStrideZ +
           std::size_t((x & mask) + (y & mask) * rowStride + (z & mask) * sliceStride);
  }

  VOXWALL_HD_INLINE float voxel(int x, int y, int z) const {
    return float(bricks[offset(clampIndex(x, dimX), clampIndex(y, dimY), clampIndex(z, dimZ))]);
  }

  // Per-ray state for sample(x, y, z, cache): the eight corners of the last voxel cell. At a
  // 1/4-voxel step most consecutive samples fall in the same cell and reuse them.
  struct RayCache {
    int ix = -1, iy = -1, iz = -1;
    float c[8] = {};
    CellGradient grad;  // the corner differences of the last shaded cell
  };

  // Trilinear sample with clamp-to-edge. Clamping the position to [0, dim - 1] gives the same
  // value as clamping the corner indices, and makes the floor a plain truncation.
  VOXWALL_HD_INLINE float sample(float x, float y, float z) const {
    RayCache cache;
    return sample(x, y, z, cache);
  }

  // A gradient neighbour: leaves the cache (the main sample's cell) alone.
  VOXWALL_HD_INLINE float sampleNear(float x, float y, float z, RayCache&) const {
    return sample(x, y, z);
  }

  VOXWALL_HD_INLINE float sample(float x, float y, float z, RayCache& cache) const {
    x = clampPosition(x, maxX), y = clampPosition(y, maxY), z = clampPosition(z, maxZ);
    const int ix = int(x), iy = int(y), iz = int(z);
    const float tx = x - float(ix), ty = y - float(iy), tz = z - float(iz);
    float* c = cache.c;
    if (ix != cache.ix || iy != cache.iy || iz != cache.iz) {
      const T* p = bricks + offset(ix, iy, iz);  // corner (ix + 1, ...) is in the apron
      const int sy = rowStride, sz = sliceStride;
      c[0] = float(p[0]), c[1] = float(p[1]), c[2] = float(p[sy]), c[3] = float(p[sy + 1]);
      c[4] = float(p[sz]), c[5] = float(p[sz + 1]), c[6] = float(p[sz + sy]);
      c[7] = float(p[sz + sy + 1]);
      cache.ix = ix, cache.iy = iy, cache.iz = iz;
    }
    return blendCorners(c, tx, ty, tz);
  }

  // The 24 voxels around cell (ix, iy, iz) that cornerDifferences reads: straight from the brick
  // when they all lie in it (its core and apron: seven cells in eight for 16^3 bricks), else
  // clamped one by one.
  struct InBrick {
    const T* p;  // the cell's lower corner in its brick
    int sy, sz;
    VOXWALL_HD_INLINE float operator()(int ox, int oy, int oz) const {
      return float(p[ox + oy * sy + oz * sz]);
    }
  };
  struct Clamped {
    const RawView* view;
    int ix, iy, iz;
    VOXWALL_HD_INLINE float operator()(int ox, int oy, int oz) const {
      return view->voxel(ix + ox, iy + oy, iz + oz);
    }
  };
  VOXWALL_HD_INLINE bool inBrickAround(int i, int dim) const {
    const int w = i & mask;
    return w >= 1 && w + 2 <= mask + 1 && i + 2 < dim;
  }

  // The gradient hook (GradientView): after sample(x, y, z, cache) at the same position.
  VOXWALL_HD_INLINE bool gradient(float x, float y, float z, RayCache& cache, float* g) const {
    if (outsideGrid(x, y, z, maxX, maxY, maxZ)) return false;
    const int ix = int(x), iy = int(y), iz = int(z);
    if (!cache.grad.holds(ix, iy, iz)) {
      if (inBrickAround(ix, dimX) && inBrickAround(iy, dimY) && inBrickAround(iz, dimZ))
        cornerDifferences(cache.c, InBrick{bricks + offset(ix, iy, iz), rowStride, sliceStride},
                          cache.grad.d);
      else
        cornerDifferences(cache.c, Clamped{this, ix, iy, iz}, cache.grad.d);
      cache.grad.ix = ix, cache.grad.iy = iy, cache.grad.iz = iz;
    }
    cache.grad.blend(x - float(ix), y - float(iy), z - float(iz), g);
    return true;
  }
};

static_assert(std::is_trivially_copyable_v<RawView<std::uint8_t>>);
static_assert(std::is_trivially_copyable_v<RawView<float>>);

}  // namespace voxwall::codec::kernels
