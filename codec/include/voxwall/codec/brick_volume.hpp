// Host-side work over a CachedBrickView's decoder, shared by every brick-decoding codec: the
// value-range grid for empty-space skipping and the full reconstruction of the volume.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <glm/vec2.hpp>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>
#include <voxwall/codec/host_tables.hpp>
#include <voxwall/codec/kernels/cached_brick_view.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {

// lo[i] = min(lo[i], v[i]), hi[i] = max(hi[i], v[i]): a NaN in v never gets in, as in the
// per-cell loop this replaced (the compiler vectorizes both loops).
inline void minMaxInto(const float* v, std::size_t n, float* lo, float* hi) {
  for (std::size_t i = 0; i < n; ++i) lo[i] = std::min(lo[i], v[i]);
  for (std::size_t i = 0; i < n; ++i) hi[i] = std::max(hi[i], v[i]);
}
inline void minMaxInto(const float* vlo, const float* vhi, std::size_t n, float* lo, float* hi) {
  for (std::size_t i = 0; i < n; ++i) lo[i] = std::min(lo[i], vlo[i]);
  for (std::size_t i = 0; i < n; ++i) hi[i] = std::max(hi[i], vhi[i]);
}

// Value ranges per cell of `cell` voxels, dilated by exactly one voxel as RangeGrid promises (a
// looser range skips less: dilating by a whole brick made the brick codecs take a third more
// samples than raw data on the same volume), held in `type` (the volume's), from the volume's
// voxels as floats that `fill(y0, y1, z0, z1, slice)` writes: every voxel x = 0 .. dims.x - 1,
// y = y0 .. y1, z = z0 .. z1, slice(z) + (y - y0) * dims.x + x. A fill never crosses a multiple
// of `align` in z (the codec's bricks: one row of them at a time), and chunks in y start at
// multiples of it where they can.
//
// Each task takes a chunk of rows in y (at most as many as its slices of `slabBytes` hold) and a
// segment of cell rows in z, which it walks upwards through a ring of align + 5 slices: a cell
// row reads its 4 slices and the one either side, and a brick row is filled once, when the cell
// row that first reaches it needs it. A brick is decoded once per task, and once more where the
// chunks and segments meet (with a slab per cell row, each brick was decoded three times in z).
// There are at least two tasks a core. A worker takes its ring once and never zeroes it (every
// slice is filled before it is read). A cell's range is taken separably: the cell row's slices
// into one, then its rows in y, then its voxels in x (a loop over each cell's 6^3 voxels was a
// quarter of a small frame's job on vq, opening included).
//
// Under a hosttables::RangeShare with a shared file (the ranks of a job on one host), the
// processes making the same grid at once split its tasks: each takes the tasks none has taken
// (the split is by the host's cores), then the others' cells from the file (low and high as
// floats, set() here exactly as where they were made); a task a process gave up (it threw) is
// made by another. The grid is the same byte for byte as one made alone.
template <class Fill>
RangeGrid slabRangeGrid(glm::ivec3 dims, ScalarType type, int cell, int align,
                        std::size_t slabBytes, Fill&& fill) {
  RangeGrid g(cell, (dims + cell - 1) / cell, type);
  const glm::ivec3 cells = g.cells();
  align = std::max(1, align);
  const int ring = align + 5;  // slices
  // Chunks in y of a whole number of cells, and of bricks where a brick holds whole cells.
  const int unit = align % cell == 0 ? align / cell : 1;                // cell rows
  const std::size_t ringRow = std::size_t(dims.x) * std::size_t(ring);  // floats a voxel row in y
  const int fits = int(std::clamp<std::size_t>(slabBytes / sizeof(float) / ringRow, 1,
                                               std::size_t(dims.y) + 2));  // voxel rows in y
  // Where chunks or segments meet, the brick row either side is decoded by both tasks: the split
  // (chunks of whole units, enough that a chunk's slices fit) decodes the fewest voxel rows among
  // those of at least two tasks a core (fewer where the volume has too few units). On 2 cores,
  // zfp's bricks of 16 in the bench's 452x555x474 MRI are decoded 1.13 times each; they were
  // decoded 1.36 times when chunks were as large as a 4 MB ring held, about four tasks a core. A
  // ring never holds more than its chunk's rows: with many cores, chunks are small.
  // Made with the host's other processes (hosttables::RangeShare): the split is by the host's
  // cores, which every process sharing the grid counts alike.
  const std::uint64_t shareKey = hosttables::rangeShareKey();
  const int workers = shareKey ? hosttables::hostCores() : resolveThreads(0);
  const int unitsY = (cells.y + unit - 1) / unit, unitsZ = (cells.z + unit - 1) / unit;
  const int maxChunkUnits = std::max(1, (fits - 2) / cell / unit);
  int chunkRows = 0, segmentRows = 0;
  double best = std::numeric_limits<double>::infinity();
  for (int cy = (unitsY + maxChunkUnits - 1) / maxChunkUnits; cy <= unitsY; ++cy) {
    const int chunkUnits = (unitsY + cy - 1) / cy, chunks = (unitsY + chunkUnits - 1) / chunkUnits;
    const int cz = std::clamp((2 * workers + chunks - 1) / chunks, 1, unitsZ);
    const int segmentUnits = (unitsZ + cz - 1) / cz,
              segs = (unitsZ + segmentUnits - 1) / segmentUnits;
    const double cost =
        (double(dims.y) + 2.0 * align * (chunks - 1)) * (double(dims.z) + 2.0 * align * (segs - 1));
    if (cost < best) best = cost, chunkRows = chunkUnits * unit, segmentRows = segmentUnits * unit;
    if (chunks * segs >= 2 * workers && cz == 1) break;  // more chunks only cut more
  }
  chunkRows = std::min(chunkRows, cells.y), segmentRows = std::min(segmentRows, cells.z);
  const int chunksY = (cells.y + chunkRows - 1) / chunkRows;
  const int segments = (cells.z + segmentRows - 1) / segmentRows;
  const std::size_t tasks = std::size_t(chunksY) * std::size_t(segments);
  // A task's cell rows: [cy0, cy1) in y, [cz0, cz1) in z.
  struct Rows {
    int cy0, cy1, cz0, cz1;
  };
  const auto rowsOf = [&](std::size_t task) {
    const int cy0 = int(task % std::size_t(chunksY)) * chunkRows;
    const int cz0 = int(task / std::size_t(chunksY)) * segmentRows;
    return Rows{cy0, std::min(cells.y, cy0 + chunkRows), cz0, std::min(cells.z, cz0 + segmentRows)};
  };
  // A task's cells into g, and into `pairs` (low, high as floats, two a cell) when given.
  struct Buffers {
    std::unique_ptr<float[]> slab, reduced;
    std::size_t capacity = 0;
  };
  const auto runTask = [&](std::size_t task, Buffers& b, float* pairs) {
    const auto [cy0, cy1, cz0, cz1] = rowsOf(task);
    // The ring's rows: the chunk's cells and one voxel either side, clamped.
    const int y0 = std::max(0, cy0 * cell - 1), y1 = std::min(dims.y - 1, cy1 * cell);
    const std::size_t sliceVoxels = std::size_t(dims.x) * std::size_t(y1 - y0 + 1);
    if (sliceVoxels * std::size_t(ring) > b.capacity) {
      b.capacity = sliceVoxels * std::size_t(ring), b.slab.reset(new float[b.capacity]);
      b.reduced.reset(new float[2 * sliceVoxels + 2 * std::size_t(dims.x)]);
    }
    const auto slice = [&](int z) { return b.slab.get() + std::size_t(z % ring) * sliceVoxels; };
    int filled = std::max(0, cz0 * cell - 1) - 1;  // the last slice filled
    for (int cz = cz0; cz < cz1; ++cz) {
      const int za = std::max(0, cz * cell - 1), zb = std::min(dims.z - 1, cz * cell + cell);
      while (filled < zb) {
        const int from = filled + 1, to = std::min(dims.z - 1, (from / align + 1) * align - 1);
        fill(y0, y1, from, to, slice);
        filled = to;
      }
      // Separably: the cell row's slices into one (per voxel of the chunk), its rows of each
      // cell row in y into one, then each cell's voxels in x.
      const float inf = std::numeric_limits<float>::infinity();
      float *zlo = b.reduced.get(), *zhi = zlo + sliceVoxels, *ylo = zhi + sliceVoxels,
            *yhi = ylo + dims.x;
      std::fill(zlo, zlo + sliceVoxels, inf), std::fill(zhi, zhi + sliceVoxels, -inf);
      for (int z = za; z <= zb; ++z) minMaxInto(slice(z), sliceVoxels, zlo, zhi);
      for (int cy = cy0; cy < cy1; ++cy) {
        const int ya = std::max(0, cy * cell - 1), yb = std::min(dims.y - 1, cy * cell + cell);
        std::fill(ylo, ylo + dims.x, inf), std::fill(yhi, yhi + dims.x, -inf);
        for (int y = ya; y <= yb; ++y) {
          const std::size_t at = std::size_t(y - y0) * std::size_t(dims.x);
          minMaxInto(zlo + at, zhi + at, std::size_t(dims.x), ylo, yhi);
        }
        for (int cx = 0; cx < cells.x; ++cx) {
          const int x0 = std::max(0, cx * cell - 1), x1 = std::min(dims.x - 1, cx * cell + cell);
          float l = inf, h = -inf;
          for (int x = x0; x <= x1; ++x) l = std::min(l, ylo[x]), h = std::max(h, yhi[x]);
          const std::size_t c = g.cellIndex(cx, cy, cz);
          g.set(c, l, h);
          if (pairs) pairs[2 * c] = l, pairs[2 * c + 1] = h;
        }
      }
    }
  };
  // The cells of a task another process made, from the shared file into g.
  const auto takeTask = [&](std::size_t task, const float* pairs) {
    const auto [cy0, cy1, cz0, cz1] = rowsOf(task);
    for (int cz = cz0; cz < cz1; ++cz)
      for (int cy = cy0; cy < cy1; ++cy)
        for (std::size_t c = g.cellIndex(0, cy, cz), e = c + std::size_t(cells.x); c < e; ++c)
          g.set(c, pairs[2 * c], pairs[2 * c + 1]);
  };
  // The shared grid: its key also names the split (processes that split otherwise share none).
  std::unique_ptr<hosttables::Region> shared;
  if (shareKey) {
    std::uint64_t key = shareKey;
    for (const std::int64_t v : {std::int64_t(dims.x), std::int64_t(dims.y), std::int64_t(dims.z),
                                 std::int64_t(type), std::int64_t(cell), std::int64_t(align),
                                 std::int64_t(chunkRows), std::int64_t(segmentRows)})
      key = hosttables::mixKey(key, std::uint64_t(v));
    shared = hosttables::Region::attach(key, tasks, g.cellCount() * 2 * sizeof(float));
  }
  float* pairs = shared ? reinterpret_cast<float*>(shared->data()) : nullptr;
  std::vector<std::uint8_t> mine(shared ? tasks : 0);  // the tasks this process made
  const int threads = std::min<int>(resolveThreads(0), int(tasks));
  std::atomic<std::size_t> nextTask{0};
  parallelFor(std::size_t(threads), threads, [&](std::size_t) {
    Buffers b;
    for (std::size_t task; (task = nextTask.fetch_add(1, std::memory_order_relaxed)) < tasks;) {
      if (!shared)
        runTask(task, b, nullptr);
      else if (shared->tryMake(task, [&] { runTask(task, b, pairs); }))
        mine[task] = 1;
    }
  });
  if (!shared) return g;
  // The other processes' tasks: their cells once made (a task a process gave up is made here).
  std::atomic<std::size_t> nextOther{0};
  parallelFor(std::size_t(threads), threads, [&](std::size_t) {
    Buffers b;
    for (std::size_t task; (task = nextOther.fetch_add(1, std::memory_order_relaxed)) < tasks;)
      if (!mine[task] && !shared->makeOnce(task, [&] { runTask(task, b, pairs); }))
        takeTask(task, pairs);
  });
  return g;
}

// slabRangeGrid over blocks of side^3 voxels that `decodeBlock(bx, by, bz, out)` decodes whole
// (side^3 values of type Value, x fastest; only those of voxels inside the volume are read), a
// row of blocks at a time; `scalar(value)` is the float the raycaster samples. The brick codecs'
// bricks and svmm's base blocks.
template <class Value, class DecodeBlock, class Scalar>
RangeGrid blockRangeGrid(glm::ivec3 dims, ScalarType type, int cell, int side,
                         std::size_t slabBytes, DecodeBlock&& decodeBlock, Scalar&& scalar) {
  return slabRangeGrid(
      dims, type, cell, side, slabBytes, [&](int y0, int y1, int z0, int z1, auto&& slice) {
        const int bz = z0 / side, blocksX = (dims.x + side - 1) / side;  // z0 .. z1: one row
        std::vector<Value> block(std::size_t(side) * std::size_t(side) * std::size_t(side));
        for (int by = y0 / side; by <= y1 / side; ++by)
          for (int bx = 0; bx < blocksX; ++bx) {
            decodeBlock(bx, by, bz, block.data());
            const int xn = std::min(side, dims.x - bx * side);
            for (int z = z0; z <= z1; ++z)
              for (int y = std::max(y0, by * side); y <= std::min(y1, by * side + side - 1); ++y) {
                const Value* in = block.data() + ((z - bz * side) * side + (y - by * side)) * side;
                float* out =
                    slice(z) + std::size_t(y - y0) * std::size_t(dims.x) + std::size_t(bx * side);
                for (int x = 0; x < xn; ++x) out[x] = scalar(in[x]);
              }
          }
      });
}

// The value ranges of a brick view's decoder. Cells are 4 voxels wide, as raw data's (the
// raycaster's skipping grid needs a power of two), or the bricks when they are 2 wide: zfp's 16^3
// bricks with cells of 16 took 2x raw's frame time on a 0.95 Gvox MRI, ksvd's 6^3 blocks with
// cells of 8 1.36x (coarse cells skip less).
template <kernels::BrickView View>
RangeGrid brickRangeGrid(const View& v, ScalarType type, std::size_t slabBytes = 16u << 20) {
  using Value = typename View::Value;
  constexpr int kSide = View::kSide;
  return blockRangeGrid<Value>(
      glm::ivec3{v.dimX, v.dimY, v.dimZ}, type, kSide == 2 ? 2 : 4, kSide, slabBytes,
      [&](int bx, int by, int bz, Value* out) { v.decoder.decode(v.decoder.key(bx, by, bz), out); },
      [&](Value x) { return v.decoder.scalar(x); });
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
