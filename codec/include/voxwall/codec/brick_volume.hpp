// Host-side work over a CachedBrickView's decoder, shared by every brick-decoding codec: the
// value-range grid for empty-space skipping and the full reconstruction of the volume.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/vec2.hpp>
#include <limits>
#include <type_traits>
#include <vector>
#include <voxwall/codec/kernels/cached_brick_view.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {

// Value ranges per cell, dilated by exactly one voxel as RangeGrid promises (a looser range skips
// less: dilating by a whole brick made the brick codecs take a third more samples than raw data
// on the same volume), held in `type` (the volume's). Cells are 4 voxels wide, as raw data's (the
// raycaster's skipping grid needs a power of two), or the bricks when they are 2 wide: zfp's 16^3
// bricks with cells of 16 took 2x raw's frame time on a 0.95 Gvox MRI, ksvd's 6^3 blocks with
// cells of 8 1.36x (coarse cells skip less). Each task takes one row of bricks' cells in z (one
// row of cells for bricks narrower than a cell) and as many cell rows in y as a slab of at most
// `slabBytes` of floats holds: it decodes the bricks under them plus the voxel around into the
// slab and takes the ranges from it. Every brick is decoded up to three times in z and a few
// percent more where the y chunks meet, on every core; the slabs, not the volume's size, bound
// what the tasks hold (a whole slice's slab was 24 MB a core at 0.95 Gvox, 100 MB at 2048^2).
template <kernels::BrickView View>
RangeGrid brickRangeGrid(const View& v, ScalarType type, std::size_t slabBytes = 4u << 20) {
  constexpr int kSide = View::kSide;
  constexpr int kCell = kSide == 2 ? 2 : 4;
  constexpr int kRows = kSide % kCell == 0 ? kSide / kCell : 1;  // cell rows in z per task
  RangeGrid g(kCell, (glm::ivec3{v.dimX, v.dimY, v.dimZ} + kCell - 1) / kCell, type);
  const glm::ivec3 cells = g.cells();
  const int bricksZ = (v.dimZ + kSide - 1) / kSide;
  const std::size_t slabRow = std::size_t(v.dimX) * std::size_t(kRows * kCell + 2);  // floats
  const int chunkRows = int(std::clamp<std::size_t>(slabBytes / sizeof(float) / (slabRow * kCell),
                                                    1, std::size_t(cells.y)));  // cell rows in y
  const int chunksY = (cells.y + chunkRows - 1) / chunkRows;
  const int tasksZ = (cells.z + kRows - 1) / kRows;
  parallelFor(std::size_t(tasksZ) * std::size_t(chunksY), 0, [&](std::size_t task) {
    const int cz0 = int(task / std::size_t(chunksY)) * kRows, cz1 = std::min(cells.z, cz0 + kRows);
    const int cy0 = int(task % std::size_t(chunksY)) * chunkRows,
              cy1 = std::min(cells.y, cy0 + chunkRows);
    // The slab: voxels y0 .. y1, z0 .. z1 (the cells and one voxel either side, clamped).
    const int z0 = std::max(0, cz0 * kCell - 1), z1 = std::min(v.dimZ - 1, cz1 * kCell);
    const int y0 = std::max(0, cy0 * kCell - 1), y1 = std::min(v.dimY - 1, cy1 * kCell);
    const std::size_t sliceVoxels = std::size_t(v.dimX) * std::size_t(y1 - y0 + 1);
    std::vector<float> slab(sliceVoxels * std::size_t(z1 - z0 + 1));
    auto at = [&](int x, int y, int z) {
      return std::size_t(z - z0) * sliceVoxels + std::size_t(y - y0) * std::size_t(v.dimX) +
             std::size_t(x);
    };
    typename View::Value vox[View::kVoxels];
    for (int bz = z0 / kSide; bz <= std::min(bricksZ - 1, z1 / kSide); ++bz)
      for (int by = y0 / kSide; by <= y1 / kSide; ++by)
        for (int bx = 0; bx < v.bricksX; ++bx) {
          v.decoder.decode(v.decoder.key(bx, by, bz), vox);
          for (int z = std::max(z0, bz * kSide); z <= std::min(z1, bz * kSide + kSide - 1); ++z)
            for (int y = std::max(y0, by * kSide); y <= std::min(y1, by * kSide + kSide - 1); ++y)
              for (int x = bx * kSide; x < std::min(v.dimX, bx * kSide + kSide); ++x)
                slab[at(x, y, z)] = v.decoder.scalar(
                    vox[(x - bx * kSide) + kSide * ((y - by * kSide) + kSide * (z - bz * kSide))]);
        }
    for (int cz = cz0; cz < cz1; ++cz)
      for (int cy = cy0; cy < cy1; ++cy)
        for (int cx = 0; cx < cells.x; ++cx) {
          const int x0 = std::max(0, cx * kCell - 1), x1 = std::min(v.dimX - 1, cx * kCell + kCell);
          const int ya = std::max(0, cy * kCell - 1), yb = std::min(v.dimY - 1, cy * kCell + kCell);
          const int za = std::max(0, cz * kCell - 1), zb = std::min(v.dimZ - 1, cz * kCell + kCell);
          float l = std::numeric_limits<float>::infinity(), h = -l;
          for (int z = za; z <= zb; ++z)
            for (int y = ya; y <= yb; ++y) {
              const float* row = slab.data() + at(0, y, z);
              for (int x = x0; x <= x1; ++x) l = std::min(l, row[x]), h = std::max(h, row[x]);
            }
          g.set(g.cellIndex(cx, cy, cz), l, h);
        }
  });
  return g;
}

// Decodes the bricks of row `bz` into `slab`: slices bz*kSide .. (those inside the volume), x
// fastest, in `type` (integer types clamp and round the decoded values to the type's range).
template <kernels::BrickView View, class T>
void decodeBrickRow(const View& v, int bz, T* slab) {
  constexpr int kSide = View::kSide;
  const std::size_t sliceVoxels = std::size_t(v.dimX) * std::size_t(v.dimY);
  typename View::Value vox[View::kVoxels];
  for (int by = 0; by < v.bricksY; ++by)
    for (int bx = 0; bx < v.bricksX; ++bx) {
      v.decoder.decode(v.decoder.key(bx, by, bz), vox);
      for (int z = 0; z < kSide; ++z)
        for (int y = 0; y < kSide; ++y)
          for (int x = 0; x < kSide; ++x) {
            const int vx = bx * kSide + x, vy = by * kSide + y, vz = bz * kSide + z;
            if (vx >= v.dimX || vy >= v.dimY || vz >= v.dimZ) continue;
            const float value = v.decoder.scalar(vox[x + kSide * (y + kSide * z)]);
            T& out = slab[std::size_t(z) * sliceVoxels + std::size_t(vy) * std::size_t(v.dimX) +
                          std::size_t(vx)];
            if constexpr (std::is_integral_v<T>) {
              const float lo = float(std::numeric_limits<T>::min());
              const float hi = float(std::numeric_limits<T>::max());
              out = T(std::clamp(std::nearbyint(value), lo, hi));
            } else {
              out = T(value);
            }
          }
    }
}

// The whole volume from its bricks, in `type`. Decodes every brick once, on every core.
template <kernels::BrickView View>
Volume decodeBricks(const View& v, ScalarType type, glm::dvec3 spacing) {
  constexpr int kSide = View::kSide;
  Volume out = Volume::allocate({v.dimX, v.dimY, v.dimZ}, type, spacing);
  const int bricksZ = (v.dimZ + kSide - 1) / kSide;
  dispatchScalar(type, [&](auto t) {
    using T = decltype(t);
    auto dst = out.as<T>();
    parallelFor(std::size_t(bricksZ), 0, [&](std::size_t bz) {
      decodeBrickRow(v, int(bz), dst.data() + out.index(0, 0, int(bz) * kSide));
    });
  });
  out.computeRange();
  return out;
}

// psnr() of the volume `reference` reads against the bricks' reconstruction (in the reference's
// type), a few rows of bricks at a time: the same value as psnr() of the two whole volumes.
template <kernels::BrickView View>
double brickPsnr(const VolumeSource& reference, const View& v) {
  constexpr int kSide = View::kSide;
  const int bricksZ = (v.dimZ + kSide - 1) / kSide;
  const int rowsPerSlab = std::max(1, 64 / kSide);
  PsnrSum sum(reference.headerVolume());
  dispatchScalar(reference.type, [&](auto t) {
    using T = decltype(t);
    const std::size_t slabVoxels = std::size_t(rowsPerSlab * kSide) * reference.sliceVoxels();
    std::vector<T> decoded(slabVoxels), original(slabVoxels);
    for (int bz0 = 0; bz0 < bricksZ; bz0 += rowsPerSlab) {
      const int rows = std::min(rowsPerSlab, bricksZ - bz0);
      parallelFor(std::size_t(rows), 0, [&](std::size_t r) {
        decodeBrickRow(v, bz0 + int(r),
                       decoded.data() + r * std::size_t(kSide) * reference.sliceVoxels());
      });
      const int z0 = bz0 * kSide, slices = std::min(rows * kSide, v.dimZ - z0);
      reference.readSlices(z0, slices, std::as_writable_bytes(std::span(original)));
      sum.add(original.data(), decoded.data(), std::size_t(slices) * reference.sliceVoxels());
    }
  });
  return sum.psnr();
}

}  // namespace voxwall::codec
