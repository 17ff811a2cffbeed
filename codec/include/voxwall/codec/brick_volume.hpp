// Host-side work over a CachedBrickView's decoder, shared by every brick-decoding codec: the
// value-range grid for empty-space skipping and the full reconstruction of the volume.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/vec2.hpp>
#include <limits>
#include <type_traits>
#include <voxwall/codec/kernels/cached_brick_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/volume.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {

// Value ranges per brick (one cell per brick), dilated by one brick: a superset of the
// one-voxel dilation the raycaster relies on. Bricks whose side is not a power of two (the
// raycaster's skipping grid needs one) are gathered into cells of 8 voxels. Decodes every brick
// once, on every core.
template <kernels::BrickView View>
RangeGrid brickRangeGrid(const View& v) {
  constexpr int kVoxels = View::kVoxels;
  RangeGrid g;
  g.cellVoxels = View::kSide;
  g.cells = {v.bricksX, v.bricksY, (v.dimZ + View::kSide - 1) / View::kSide};
  const std::size_t n = g.cellCount();
  std::vector<float> lo(n), hi(n);
  auto cell = [&](int x, int y, int z) {
    return (std::size_t(z) * std::size_t(g.cells.y) + std::size_t(y)) * std::size_t(g.cells.x) +
           std::size_t(x);
  };
  parallelFor(std::size_t(g.cells.z), 0, [&](std::size_t bz) {
    typename View::Value vox[kVoxels];
    for (int by = 0; by < g.cells.y; ++by)
      for (int bx = 0; bx < g.cells.x; ++bx) {
        v.decoder.decode(v.decoder.key(bx, by, int(bz)), vox);
        float l = std::numeric_limits<float>::infinity(), h = -l;
        for (int i = 0; i < kVoxels; ++i) {
          const float s = v.decoder.scalar(vox[i]);
          l = std::min(l, s), h = std::max(h, s);
        }
        const std::size_t i = cell(bx, by, int(bz));
        lo[i] = l, hi[i] = h;
      }
  });
  g.lo.resize(n), g.hi.resize(n);
  parallelFor(std::size_t(g.cells.z), 0, [&](std::size_t zs) {
    const int z = int(zs);
    for (int y = 0; y < g.cells.y; ++y)
      for (int x = 0; x < g.cells.x; ++x) {
        float l = std::numeric_limits<float>::infinity(), h = -l;
        for (int dz = std::max(0, z - 1); dz <= std::min(g.cells.z - 1, z + 1); ++dz)
          for (int dy = std::max(0, y - 1); dy <= std::min(g.cells.y - 1, y + 1); ++dy)
            for (int dx = std::max(0, x - 1); dx <= std::min(g.cells.x - 1, x + 1); ++dx) {
              const std::size_t j = cell(dx, dy, dz);
              l = std::min(l, lo[j]), h = std::max(h, hi[j]);
            }
        const std::size_t i = cell(x, y, z);
        g.lo[i] = l, g.hi[i] = h;
      }
  });
  if constexpr ((View::kSide & (View::kSide - 1)) == 0) {
    return g;
  } else {
    // The raycaster's skipping grid needs power-of-two cells: cells of 8 voxels, each the union
    // of the (dilated) ranges of the bricks its voxels lie in.
    constexpr int kCell = 8;
    RangeGrid p;
    p.cellVoxels = kCell;
    p.cells = (glm::ivec3{v.dimX, v.dimY, v.dimZ} + kCell - 1) / kCell;
    p.lo.resize(p.cellCount()), p.hi.resize(p.cellCount());
    const glm::ivec3 dims{v.dimX, v.dimY, v.dimZ};
    parallelFor(std::size_t(p.cells.z), 0, [&](std::size_t zs) {
      const int z = int(zs);
      auto span = [&](int c, int axis) {
        return glm::ivec2{c * kCell / View::kSide,
                          std::min(c * kCell + kCell - 1, dims[axis] - 1) / View::kSide};
      };
      const glm::ivec2 bz = span(z, 2);
      for (int y = 0; y < p.cells.y; ++y)
        for (int x = 0; x < p.cells.x; ++x) {
          const glm::ivec2 by = span(y, 1), bx = span(x, 0);
          float l = std::numeric_limits<float>::infinity(), h = -l;
          for (int k = bz.x; k <= bz.y; ++k)
            for (int j = by.x; j <= by.y; ++j)
              for (int i = bx.x; i <= bx.y; ++i) {
                const std::size_t c = cell(i, j, k);
                l = std::min(l, g.lo[c]), h = std::max(h, g.hi[c]);
              }
          const std::size_t out =
              (std::size_t(z) * std::size_t(p.cells.y) + std::size_t(y)) * std::size_t(p.cells.x) +
              std::size_t(x);
          p.lo[out] = l, p.hi[out] = h;
        }
    });
    return p;
  }
}

// The whole volume from its bricks, in `info`'s scalar type (integer types clamp and round the
// decoded values to the type's range). Decodes every brick once, on every core.
template <kernels::BrickView View>
Volume decodeBricks(const View& v, ScalarType type, glm::dvec3 spacing) {
  constexpr int kSide = View::kSide;
  Volume out = Volume::allocate({v.dimX, v.dimY, v.dimZ}, type, spacing);
  const int bricksZ = (v.dimZ + View::kSide - 1) / View::kSide;
  dispatchScalar(type, [&](auto t) {
    using T = decltype(t);
    auto dst = out.as<T>();
    parallelFor(std::size_t(bricksZ), 0, [&](std::size_t bz) {
      typename View::Value vox[View::kVoxels];
      for (int by = 0; by < v.bricksY; ++by)
        for (int bx = 0; bx < v.bricksX; ++bx) {
          v.decoder.decode(v.decoder.key(bx, by, int(bz)), vox);
          for (int z = 0; z < kSide; ++z)
            for (int y = 0; y < kSide; ++y)
              for (int x = 0; x < kSide; ++x) {
                const int vx = bx * kSide + x, vy = by * kSide + y, vz = int(bz) * kSide + z;
                if (vx >= v.dimX || vy >= v.dimY || vz >= v.dimZ) continue;
                const float value = v.decoder.scalar(vox[x + kSide * (y + kSide * z)]);
                if constexpr (std::is_integral_v<T>) {
                  const float lo = float(std::numeric_limits<T>::min());
                  const float hi = float(std::numeric_limits<T>::max());
                  dst[out.index(vx, vy, vz)] = T(std::clamp(std::nearbyint(value), lo, hi));
                } else {
                  dst[out.index(vx, vy, vz)] = T(value);
                }
              }
        }
    });
  });
  out.computeRange();
  return out;
}

}  // namespace voxwall::codec
