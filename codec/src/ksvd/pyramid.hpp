// The ksvd encoder's pyramid of levels: each level's voxels the mean of the 2x2x2 below it, read
// a window of slices at a time (level 0 from the input, level 1 of an input that streams made from
// it two slices at a time as it is read), and how many levels a volume gets. Internal to the
// encoder (codec.cpp).
#pragma once

#include <algorithm>
#include <glm/common.hpp>
#include <span>
#include <vector>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec::ksvd {

// Row y0 .. y1 - 1 of slice z of the level above `below` (whose at() must reach its slices 2z and
// 2z + 1): each voxel the mean of the 2x2x2 voxels below it, clamped at the far faces, into
// `out` (the slice's voxels, x fastest).
template <class Below>
void halveRows(const Below& below, glm::ivec3 dims, int z, int y0, int y1, float* out) {
  for (int y = y0; y < y1; ++y)
    for (int x = 0; x < dims.x; ++x) {
      double sum = 0;
      for (int j = 0; j < 8; ++j)
        sum += below.at(2 * x + (j & 1), 2 * y + ((j >> 1) & 1), 2 * z + (j >> 2));
      out[std::size_t(y) * std::size_t(dims.x) + std::size_t(x)] = float(sum / 8.0);
    }
}

// One level of the pyramid: level 0 reads a window of the input's slices (all of them when the
// input is in memory); a coarser level its floats, a window of them (level 1 of an input that
// streams) or all of them.
template <class T>
struct Source {
  bool base = false;        // level 0: `data`, else `floats`
  std::span<const T> data;  // slices z0 .. z0 + slices - 1
  std::span<const float> floats;
  int z0 = 0, slices = 0;
  Volume coarse;  // a coarser level held whole: float32, value range computed
  glm::ivec3 dims;
  // Voxel (x, y, z), clamped at the far faces; z must be in the window.
  float at(int x, int y, int z) const {
    x = std::min(x, dims.x - 1), y = std::min(y, dims.y - 1), z = std::min(z, dims.z - 1);
    const std::size_t i =
        (std::size_t(z - z0) * std::size_t(dims.y) + std::size_t(y)) * std::size_t(dims.x) +
        std::size_t(x);
    return base ? float(data[i]) : floats[i];
  }
  // Block b's voxels (edge-padded), minus `lo`, divided by `scale`.
  void block(glm::ivec3 b, int m, float lo, float scale, float* out) const {
    const float inv = 1.0f / scale;
    for (int z = 0, i = 0; z < m; ++z)
      for (int y = 0; y < m; ++y)
        for (int x = 0; x < m; ++x, ++i)
          out[i] = (at(b.x * m + x, b.y * m + y, b.z * m + z) - lo) * inv;
  }
  // The next level: each voxel the mean of the 2x2x2 voxels below it (clamped at the far faces).
  // `window(z0, z1)` makes this level's slices z0 .. z1 - 1 readable; the slices are made a
  // slab at a time, in order.
  template <class Window>
  Source halved(glm::dvec3 spacing, int threads, Window&& window) const {
    Source out;
    out.dims = (dims - 1) / 2 + 1;
    out.coarse = Volume::allocate(out.dims, ScalarType::Float32, spacing);
    const std::span<float> values = out.coarse.template as<float>();
    const std::size_t slice = std::size_t(out.dims.x) * std::size_t(out.dims.y);
    constexpr int kSlab = 32;  // slices of the new level a window serves
    for (int first = 0; first < out.dims.z; first += kSlab) {
      const int last = std::min(first + kSlab, out.dims.z);
      window(2 * first, std::min(2 * last, dims.z));
      parallelFor(std::size_t(last - first), threads, [&](std::size_t i) {
        const int z = first + int(i);
        halveRows(*this, out.dims, z, 0, out.dims.y, values.data() + std::size_t(z) * slice);
      });
    }
    out.coarse.computeRange();
    out.floats = values, out.slices = out.dims.z;
    return out;
  }
};

// Level 1 of the pyramid of an input that streams, made from it two slices at a time as it is
// read (float32, as Source::halved makes it); valueMin and valueMax are the caller's to set.
template <class T>
class HalvedSource final : public VolumeSource {
 public:
  HalvedSource(const VolumeSource& below, glm::dvec3 levelSpacing, int threads)
      : below_(below), threads_(threads) {
    dims = (below.dims - 1) / 2 + 1, spacing = levelSpacing;
    orientation = below.orientation, type = ScalarType::Float32;
  }
  bool streams() const override { return true; }
  const Volume* inMemory() const override { return nullptr; }

 protected:
  void read(int z0, int count, std::byte* out) const override {
    std::vector<T> pair(2 * below_.sliceVoxels());
    Source<T> two;
    two.base = true, two.dims = below_.dims, two.data = pair, two.slices = 2;
    for (int z = z0; z < z0 + count; ++z) {
      below_.readSlices(2 * z, 2, std::as_writable_bytes(std::span(pair)));  // 2z + 1 clamped
      two.z0 = 2 * z;
      auto* slice = reinterpret_cast<float*>(out + std::size_t(z - z0) * sliceBytes());
      const int rows = std::max(1, dims.y / 16);
      parallelFor(std::size_t((dims.y + rows - 1) / rows), threads_, [&](std::size_t r) {
        const int y0 = int(r) * rows;
        halveRows(two, dims, z, y0, std::min(y0 + rows, dims.y), slice);
      });
    }
  }

 private:
  const VolumeSource& below_;
  int threads_;
};

// Pyramid levels: `requested`, or (0) until a level fits in one brick.
inline int levelCount(glm::ivec3 dims, int brickVoxels, int requested) {
  if (requested > 0) return requested;
  int levels = 1;
  while (levels < kernels::kKsvdMaxLevels && std::max({dims.x, dims.y, dims.z}) > brickVoxels)
    dims = (dims - 1) / 2 + 1, ++levels;
  return levels;
}

}  // namespace voxwall::codec::ksvd
