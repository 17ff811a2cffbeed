#include <algorithm>
#include <limits>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {

RangeGrid computeRangeGrid(const Volume& volume, int cellVoxels) {
  return computeRangeGrid(*memorySource(volume), cellVoxels);
}

RangeGrid computeRangeGrid(const VolumeSource& source, int cellVoxels) {
  if (cellVoxels < 1) throw std::invalid_argument("range grid cell size must be positive");
  RangeGrid grid;
  grid.cellVoxels = cellVoxels;
  grid.cells = (source.dims + cellVoxels - 1) / cellVoxels;
  grid.lo.resize(grid.cellCount());
  grid.hi.resize(grid.cellCount());
  const glm::ivec3 d = source.dims;
  // One row of cells at a time, from its slices and the one either side (the dilation).
  std::vector<std::byte> window(std::size_t(cellVoxels + 2) * source.sliceBytes());
  dispatchScalar(source.type, [&](auto t) {
    using T = decltype(t);
    for (int cz = 0; cz < grid.cells.z; ++cz) {
      const int z0 = std::max(0, cz * cellVoxels - 1),
                z1 = std::min(d.z, (cz + 1) * cellVoxels + 1);
      source.readSlices(z0, z1 - z0, window);
      const T* values = reinterpret_cast<const T*>(window.data());
      parallelFor(std::size_t(grid.cells.y), 0, [&](std::size_t cyIndex) {
        const int cy = int(cyIndex);
        const int y0 = std::max(0, cy * cellVoxels - 1),
                  y1 = std::min(d.y, (cy + 1) * cellVoxels + 1);
        for (int cx = 0; cx < grid.cells.x; ++cx) {
          const int x0 = std::max(0, cx * cellVoxels - 1),
                    x1 = std::min(d.x, (cx + 1) * cellVoxels + 1);
          float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
          for (int z = z0; z < z1; ++z)
            for (int y = y0; y < y1; ++y) {
              const T* line = values + (std::size_t(z - z0) * std::size_t(d.y) + std::size_t(y)) *
                                           std::size_t(d.x);
              for (int x = x0; x < x1; ++x) {
                const float v = float(line[x]);
                lo = std::min(lo, v);
                hi = std::max(hi, v);
              }
            }
          const std::size_t c = (std::size_t(cz) * std::size_t(grid.cells.y) + std::size_t(cy)) *
                                    std::size_t(grid.cells.x) +
                                std::size_t(cx);
          grid.lo[c] = lo;
          grid.hi[c] = hi;
        }
      });
    }
  });
  return grid;
}

}  // namespace voxwall::codec
