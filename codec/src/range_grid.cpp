#include <zlib.h>

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {

RangeGrid computeRangeGrid(const Volume& volume, int cellVoxels) {
  return computeRangeGrid(*memorySource(volume), cellVoxels);
}

RangeGrid::RangeGrid(int cellVoxels, glm::ivec3 cells, ScalarType type)
    : cellVoxels_(cellVoxels), cells_(cells), type_(type) {
  dispatchScalar(type, [&]<class T>(T) {
    const Pair<T> empty{std::numeric_limits<T>::max(), std::numeric_limits<T>::lowest()};
    bytes_.resize(cellCount() * sizeof empty);
    for (std::size_t c = 0; c < cellCount(); ++c) put<T>(c, empty);
  });
}

void RangeGrid::pack() {
  if (packed_) return;
  const std::size_t n = cellCount(), chunks = (n + kChunkCells - 1) / kChunkCells;
  std::vector<std::vector<std::byte>> parts(chunks);
  parallelFor(chunks, 0, [&](std::size_t k) {
    const std::size_t first = k * kChunkCells, count = std::min(kChunkCells, n - first);
    const auto* in = reinterpret_cast<const Bytef*>(bytes_.data() + first * pairBytes());
    const uLong inBytes = uLong(count * pairBytes());
    uLongf outBytes = compressBound(inBytes);
    parts[k].resize(outBytes);
    if (compress2(reinterpret_cast<Bytef*>(parts[k].data()), &outBytes, in, inBytes, 1) != Z_OK)
      throw std::runtime_error("range grid: zlib could not compress a chunk");
    parts[k].resize(outBytes);
  });
  chunkOffsets_.assign(1, 0);
  for (const auto& part : parts) chunkOffsets_.push_back(chunkOffsets_.back() + part.size());
  packedBytes_.reserve(chunkOffsets_.back());
  for (auto& part : parts) {
    packedBytes_.insert(packedBytes_.end(), part.begin(), part.end());
    std::vector<std::byte>().swap(part);
  }
  std::vector<std::byte>().swap(bytes_);
  packed_ = true;
}

void RangeGrid::inflateChunk(std::size_t k, std::span<std::byte> out) const {
  uLongf outBytes = uLongf(out.size());
  const int status =
      uncompress(reinterpret_cast<Bytef*>(out.data()), &outBytes,
                 reinterpret_cast<const Bytef*>(packedBytes_.data() + chunkOffsets_[k]),
                 uLong(chunkOffsets_[k + 1] - chunkOffsets_[k]));
  // The chunks were made in this process: a failure is a bug (or memory gone bad), not input.
  if (status != Z_OK || outBytes != out.size())
    throw std::logic_error("range grid: a packed chunk does not inflate to its cells");
}

RangeGrid computeRangeGrid(const VolumeSource& source, int cellVoxels) {
  if (cellVoxels < 1) throw std::invalid_argument("range grid cell size must be positive");
  RangeGrid grid(cellVoxels, (source.dims + cellVoxels - 1) / cellVoxels, source.type);
  const std::size_t layer = std::size_t(grid.cells().x) * std::size_t(grid.cells().y);
  forEachRangeLayer(source, cellVoxels,
                    [&](int cz, std::span<const float> lo, std::span<const float> hi) {
                      for (std::size_t i = 0; i < lo.size(); ++i)
                        grid.set(std::size_t(cz) * layer + i, lo[i], hi[i]);
                    });
  return grid;
}

void forEachRangeLayer(
    const VolumeSource& source, int cellVoxels,
    const std::function<void(int, std::span<const float>, std::span<const float>)>& layerDone) {
  if (cellVoxels < 1) throw std::invalid_argument("range grid cell size must be positive");
  const glm::ivec3 cells = (source.dims + cellVoxels - 1) / cellVoxels;
  const std::size_t layer = std::size_t(cells.x) * std::size_t(cells.y);
  std::vector<float> lo(layer), hi(layer);
  const glm::ivec3 d = source.dims;
  // One layer of cells at a time, from its slices and the one either side (the dilation).
  std::vector<std::byte> window(std::size_t(cellVoxels + 2) * source.sliceBytes());
  dispatchScalar(source.type, [&](auto t) {
    using T = decltype(t);
    for (int cz = 0; cz < cells.z; ++cz) {
      const int z0 = std::max(0, cz * cellVoxels - 1),
                z1 = std::min(d.z, (cz + 1) * cellVoxels + 1);
      source.readSlices(z0, z1 - z0, window);
      const T* values = reinterpret_cast<const T*>(window.data());
      parallelFor(std::size_t(cells.y), 0, [&](std::size_t cyIndex) {
        const int cy = int(cyIndex);
        const int y0 = std::max(0, cy * cellVoxels - 1),
                  y1 = std::min(d.y, (cy + 1) * cellVoxels + 1);
        for (int cx = 0; cx < cells.x; ++cx) {
          const int x0 = std::max(0, cx * cellVoxels - 1),
                    x1 = std::min(d.x, (cx + 1) * cellVoxels + 1);
          float l = std::numeric_limits<float>::max(), h = std::numeric_limits<float>::lowest();
          for (int z = z0; z < z1; ++z)
            for (int y = y0; y < y1; ++y) {
              const T* line = values + (std::size_t(z - z0) * std::size_t(d.y) + std::size_t(y)) *
                                           std::size_t(d.x);
              for (int x = x0; x < x1; ++x) {
                const float v = float(line[x]);
                l = std::min(l, v);
                h = std::max(h, v);
              }
            }
          const std::size_t c = std::size_t(cy) * std::size_t(cells.x) + std::size_t(cx);
          lo[c] = l, hi[c] = h;
        }
      });
      layerDone(cz, lo, hi);
    }
  });
}

}  // namespace voxwall::codec
