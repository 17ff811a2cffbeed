// The `raw` codec: the volume cut into bricks, uncompressed, plus per-brick value ranges.
// It is the reference every lossy codec is compared with, and what `render` uses for plain
// volume files.
//
// Sections (ids within CodecId::Raw):
//   1 params  u32 brickShift (brick = 2^brickShift voxels per side, 2..6), u32 reserved (0)
//   2 ranges  per brick, bricks x fastest: f32 lo, f32 hi over the brick dilated by one voxel
//   3 bricks  per brick, bricks x fastest: 2^(3*brickShift) scalars of the volume's type,
//             x fastest; voxels past the volume's edge repeat the edge voxel
#pragma once

#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/raw_view.hpp>
#include <voxwall/codec/progress.hpp>
#include <voxwall/codec/range_grid.hpp>

namespace voxwall::codec::raw {

enum SectionId : std::uint32_t { kParams = 1, kRanges = 2, kBricks = 3 };

struct Params {
  int brickVoxels = 8;  // voxels per brick side: 4, 8, 16, 32 or 64
};

// Throws std::invalid_argument for a brick size that is not a power of two in 4..64.
CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress);

// The sections of a raw-coded volume, checked against the header: every size and count is
// validated before use; throws FormatError naming the source and the section.
class Layout {
 public:
  Layout(const VolumeInfo& info, const SectionSet& sections);

  int brickShift() const { return brickShift_; }
  glm::ivec3 bricks() const { return bricks_; }
  std::span<const std::byte> brickBytes() const { return brickBytes_; }
  RangeGrid rangeGrid() const;
  // The view over bricks at `base` (host memory by default, or a device copy of brickBytes()).
  template <class T>
  kernels::RawView<T> view(const std::byte* base = nullptr) const {
    kernels::RawView<T> v;
    v.bricks = reinterpret_cast<const T*>(base ? base : brickBytes_.data());
    v.dimX = info_.dims.x, v.dimY = info_.dims.y, v.dimZ = info_.dims.z;
    v.bricksX = bricks_.x, v.bricksY = bricks_.y;
    v.brickShift = brickShift_;
    return v;
  }

 private:
  VolumeInfo info_;
  int brickShift_ = 3;
  glm::ivec3 bricks_{0, 0, 0};
  std::span<const std::byte> rangeBytes_, brickBytes_;
};

// Full reconstruction.
Volume decode(const VolumeInfo& info, const SectionSet& sections);

}  // namespace voxwall::codec::raw
