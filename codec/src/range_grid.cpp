#include <algorithm>
#include <limits>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {

RangeGrid computeRangeGrid(const Volume& volume, int cellVoxels) {
  if (cellVoxels < 1) throw std::invalid_argument("range grid cell size must be positive");
  RangeGrid grid;
  grid.cellVoxels = cellVoxels;
  grid.cells = (volume.dims + cellVoxels - 1) / cellVoxels;
  grid.lo.resize(grid.cellCount());
  grid.hi.resize(grid.cellCount());
  dispatchScalar(volume.type, [&](auto t) {
    using T = decltype(t);
    auto values = volume.as<T>();
    const glm::ivec3 d = volume.dims;
    parallelFor(std::size_t(grid.cells.z) * std::size_t(grid.cells.y), 0, [&](std::size_t row) {
      const int cz = int(row / std::size_t(grid.cells.y)),
                cy = int(row % std::size_t(grid.cells.y));
      const int z0 = std::max(0, cz * cellVoxels - 1),
                z1 = std::min(d.z, (cz + 1) * cellVoxels + 1);
      const int y0 = std::max(0, cy * cellVoxels - 1),
                y1 = std::min(d.y, (cy + 1) * cellVoxels + 1);
      for (int cx = 0; cx < grid.cells.x; ++cx) {
        const int x0 = std::max(0, cx * cellVoxels - 1),
                  x1 = std::min(d.x, (cx + 1) * cellVoxels + 1);
        float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
        for (int z = z0; z < z1; ++z)
          for (int y = y0; y < y1; ++y) {
            const T* line = values.data() + volume.index(0, y, z);
            for (int x = x0; x < x1; ++x) {
              const float v = float(line[x]);
              lo = std::min(lo, v);
              hi = std::max(hi, v);
            }
          }
        const std::size_t c = row * std::size_t(grid.cells.x) + std::size_t(cx);
        grid.lo[c] = lo;
        grid.hi[c] = hi;
      }
    });
  });
  return grid;
}

}  // namespace voxwall::codec
