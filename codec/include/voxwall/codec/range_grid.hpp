// Coarse value ranges of a volume, for empty-space skipping.
#pragma once

#include <functional>
#include <span>
#include <vector>
#include <voxwall/codec/volume.hpp>

namespace voxwall::codec {

class VolumeSource;  // volume_source.hpp

// Min/max of the voxel values in each cell of cellVoxels^3 voxels, *dilated by one voxel* on
// every side (clamped at the border): every trilinear sample whose lower corner voxel lies in a
// cell interpolates only voxels the cell's range covers. Cells are x fastest.
struct RangeGrid {
  int cellVoxels = 8;
  glm::ivec3 cells{0, 0, 0};
  std::vector<float> lo, hi;
  std::size_t cellCount() const {
    return std::size_t(cells.x) * std::size_t(cells.y) * std::size_t(cells.z);
  }
};

// Computes the grid from a dense volume (multi-threaded).
RangeGrid computeRangeGrid(const Volume& volume, int cellVoxels);
// The same from a volume read a layer of cells (and the slice either side) at a time.
RangeGrid computeRangeGrid(const VolumeSource& source, int cellVoxels);
// The grid a layer of cells at a time, without holding it: layerDone(cz, lo, hi) with the cells
// of layer cz, x fastest (an encoder that stores the ranges in its own form).
void forEachRangeLayer(
    const VolumeSource& source, int cellVoxels,
    const std::function<void(int, std::span<const float>, std::span<const float>)>& layerDone);

}  // namespace voxwall::codec
