// Raw bricks: a format of the codec library, not a codec's private layout. The volume cut into
// bricks, uncompressed, plus per-cell value ranges. Whoever needs voxels laid out for rays names
// this format: the `raw` codec stores it as it is (codec/src/raw/: the reference every lossy codec
// is compared with, and what `compress` writes by default), `generate` writes it, a plain volume
// file is rendered from it (node's RenderVolume::fromVolume), node's CPU backend samples its bricks
// on vectors, and DecodedBricks turns a volume decoded whole into the bricks a device samples.
// A file of raw bricks carries the raw codec's id (kCodecId): the raw codec reads it back.
//
// Sections (ids within the codec's own):
//   1 params  u32 brickShift (brick = 2^brickShift voxels per side, 2..6),
//             u32 rangeShift (range cell = 2^rangeShift voxels per side, 1..6)
//   2 ranges  per range cell, cells x fastest: lo, hi in the volume's scalar type, over the cell
//             dilated by one voxel
//   3 bricks  per brick, bricks x fastest: (2^brickShift + 1)^3 scalars of the volume's type,
//             x fastest: the brick's voxels plus a one-voxel apron on the high side of each
//             axis (the next brick's first voxels), so a trilinear neighbourhood never spans
//             two bricks; voxels past the volume's edge repeat the edge voxel
#pragma once

#include <optional>
#include <string>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/raw_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::rawbricks {

// The codec id files of raw bricks carry (the raw codec's: RawCodecEntry::kId).
inline constexpr CodecId kCodecId{1};  // stored in files: never reused

enum SectionId : std::uint32_t { kParams = 1, kRanges = 2, kBricks = 3 };

struct Params {
  int brickVoxels = 16;     // voxels per brick side: 4, 8, 16, 32 or 64 (stored with a
                            // one-voxel apron: 16 costs 1.2x the volume, 8 costs 1.42x)
  int rangeCellVoxels = 4;  // voxels per side of an empty-space-skipping cell: 2 .. 64
};

// Throws std::invalid_argument for sizes that are not powers of two in range.
CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress);
// The same from a volume read one row of bricks (b + 1 slices) at a time: the same bytes.
CompressedVolume encode(const VolumeSource& volume, const Params& params, Progress& progress);

// The sections of a raw-coded volume, checked against the header: every size and count is
// validated before use; throws FormatError naming the source and the section.
class Layout {
 public:
  Layout(const VolumeInfo& info, const SectionSet& sections);

  int brickShift() const { return brickShift_; }
  glm::ivec3 bricks() const { return bricks_; }
  std::span<const std::byte> brickBytes() const { return brickBytes_; }
  glm::ivec3 rangeCells() const { return rangeCells_; }
  int rangeCellVoxels() const { return 1 << rangeShift_; }
  RangeGrid rangeGrid() const;
  // The view over bricks at `base` (host memory by default, or a device copy of brickBytes()).
  template <class T>
  kernels::RawView<T> view(const std::byte* base = nullptr) const {
    return kernels::RawView<T>::make(reinterpret_cast<const T*>(base ? base : brickBytes_.data()),
                                     info_.dims.x, info_.dims.y, info_.dims.z, bricks_.x, bricks_.y,
                                     brickShift_);
  }

 private:
  VolumeInfo info_;
  int brickShift_ = 3, rangeShift_ = 2;
  glm::ivec3 bricks_{0, 0, 0}, rangeCells_{0, 0, 0};
  std::span<const std::byte> rangeBytes_, brickBytes_;
};

// Full reconstruction.
Volume decode(const VolumeInfo& info, const SectionSet& sections);

// The render payload over a file's raw bricks (validated by Layout; the sections must outlive it).
std::unique_ptr<RenderPayload> openPayload(const VolumeInfo& info, const SectionSet& sections);

// A whole volume as raw bricks (the default Params), in memory with its layout: what a device
// samples of a volume whose codec it does not decode per ray, decoded once on the host. The one
// path for it (render_volume's decoded payload, zfp's device view). Not movable: the layout
// points into the bricks.
class DecodedBricks {
 public:
  DecodedBricks(const Volume& volume, const std::string& source);
  DecodedBricks(const DecodedBricks&) = delete;
  DecodedBricks& operator=(const DecodedBricks&) = delete;
  const Layout& layout() const { return *layout_; }
  // The render payload over these bricks (they must outlive it).
  std::unique_ptr<RenderPayload> payload() const;
  // The bytes the bricks of a volume of these dims and type take.
  static std::uint64_t bytesFor(glm::ivec3 dims, ScalarType type);

 private:
  CompressedVolume coded_;
  SectionSet sections_;
  std::optional<Layout> layout_;
};

}  // namespace voxwall::codec::rawbricks
