// The SVMM codec (M. E. Faas, "Sparse Voxel Mip-Maps: Versatile Lossy Compression of
// Volumetric Data", Leiden bachelor thesis, 2016).
//
// Levels. Level 0 is the volume. Level i + 1 averages w_i^3 blocks of level i (w_i a power of
// two: one width for every level, or the thesis's stepped widths 2, 4, 8, ... for levels
// 0, 1, 2, ...); level i's voxels are 2^shift_i volume voxels wide (the mipmap factor). Levels are
// built until the level's grid is at most r voxels on every side: that level is the root, one
// block holding the whole grid (padded to even sizes for sub-blocks). With a volume already at
// most r wide there is one level: the root is the volume.
//
// Compression. The block of level i under a voxel of level i + 1 is *dropped* when every voxel
// of it is terminal (all level-0 voxels are) and within delta of the equivalent voxel: the
// vector distance over channels between each voxel and the equivalent voxel *as stored* (so
// RGBA's 3-bit alpha counts), in units of the peak (the value range of scalar data, 255 per
// RGBA channel). The equivalent voxel then becomes terminal: every voxel under it reads its
// value. delta = sqrt(n) (1 - q / 100) for quality q in 0..100 and n channels: the thesis prints
// delta = 1 - sqrt(n) q / 100, which is negative for n = 4 and does not vanish at q = 100 for
// n > 1; our reading keeps its two stated intents (delta scales with sqrt(n), q = 100 is
// lossless) and delta = sqrt(n), the largest possible distance, at q = 0. Errors can add up
// over levels (a dropped block's voxels may be terminal voxels of earlier drops): at most
// levels x delta.
//
// Voxel formats. Base voxels: DENSITY8 1 byte; DENSITY16 2 bytes (12/16-bit data; int16 stored
// with a bias of 32768); RGBA32 4 bytes r, g, b, a. Non-base voxels are words (little-endian):
//   DENSITY8  u16: bits 15..8 intensity, 7..5 zero, 4 terminal, 3..0 offset nibble
//   DENSITY16 u32: bits 31..16 intensity (all 16 bits: the thesis's 16-bit layout keeps 8 and
//                  would lose 12-bit CT), 15..5 zero, 4 terminal, 3..0 offset nibble
//   RGBA32    u32: bits 31..24 r, 23..16 g, 15..8 b, 7..5 alpha / 32 rounded to 3 bits
//                  (expanded as round(a3 * 255 / 7)), 4 terminal, 3..0 offset nibble
// Sub-blocks (section 2.2.2). Every non-base block (and the root grid) is cut into 2^3
// sub-blocks; voxel j = x + 2y + 4z of a sub-block holds nibble j of the sub-block's 32-bit
// offset: the index, within the next finer level, of the block under the sub-block's first
// non-terminal voxel. The block under voxel j is offset + (non-terminal voxels before j). Blocks
// of a level are stored in the order their parents' sub-blocks are walked: parent blocks in
// their order, sub-blocks z, y, x, voxels j = 0..7.
//
// Base-level block compression (flag 1, section 2.1.1, Fig. 1.2c): each base block is stored
// as (w_0 / 2)^3 groups of 2^3 voxels, x fastest, each a bitmap byte (bit j: voxel j is
// non-zero, for RGBA: has non-zero alpha) and one value (the mean of the non-zero voxels; 1, 2
// or 4 bytes). Lossy even at q = 100; a one-level file ignores it.
//
// Sections:
//   1 "params": u32 format (1 DENSITY8, 2 DENSITY16, 3 RGBA32), u32 flags (1 block-compressed
//     base), i32 bias, u32 quality, f64 delta, f64 peak, u32 root width r, u32 stepped (0/1),
//     u32 levels n (1..16), u32 root grid x, y, z, then per level 0..n-1: u32 block width
//     (the root: 0), u32 shift, u64 blocks, u64 byte offset in "data", u64 bytes; then f64
//     psnr of the decoded volume (+inf when lossless).
//   2 "data": the levels, root first, each starting at a multiple of 8 bytes.
// Voxels outside the volume (padding) are stored as terminal zeros.
#pragma once

#include <cstdint>
#include <glm/common.hpp>
#include <string>
#include <vector>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/svmm_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::svmm {

enum SectionId : std::uint32_t { kParams = 1, kData = 2 };
enum Flags : std::uint32_t { kBlockCompressed = 1 };

struct Params {
  int quality = 100;     // 0..100; 100 is lossless (without block compression)
  int blockWidth = 4;    // one power of two in 2..64 for every level (ignored when stepped)
  bool stepped = false;  // widths 2, 4, 8, ... for levels 0, 1, 2, ...
  int rootWidth = 32;    // stop when a level is at most this wide (>= 2)
  bool baseCompression = false;
  int threads = 0;  // 0: every usable core
  // Level 1 is built from windows of about this many bytes of the input (at least one row of
  // blocks); the base level is written from slabs of 2 w0 slices whatever this says.
  std::size_t windowBytes = std::size_t(64) << 20;
};

// delta for a quality and a channel count (see the file comment).
double deltaForQuality(int quality, int channels);

struct EncodeStats {
  int levels = 0;
  std::vector<std::uint64_t> blocks;  // stored blocks per level (level 0 first; root = 1)
  std::vector<int> widths;            // block width per level (root: 0)
  std::uint64_t dataBytes = 0;
  double delta = 0, psnr = 0;
};

// An RGBA32 volume (r | g << 8 | b << 16 | a << 24 per voxel, x fastest).
struct RgbaVolume {
  glm::ivec3 dims{0, 0, 0};
  glm::dvec3 spacing{1, 1, 1};
  std::vector<std::uint32_t> rgba;
};

// uint8 -> DENSITY8, uint16 / int16 -> DENSITY16; float32 is refused (std::invalid_argument).
// Streams: level 1 is built from a window of slices at a time, the base level is written from a
// second pass of slabs of 2 w0 slices straight to its blocks' places, and the PSNR is summed on
// the way; the encoder holds the file, levels 1 and up and one window.
CompressedVolume encode(const VolumeSource& source, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);
CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);
// RGBA32 (stored with scalar type uint8 and value range 0..255 in the header).
CompressedVolume encodeRgba(const RgbaVolume& volume, const Params& params, Progress& progress,
                            EncodeStats* stats = nullptr);

// Validated description of an SVMM file: every params field, every level's extent in the data,
// and every sub-block's child offset (a file that passes cannot make a view read outside it).
class Layout {
 public:
  Layout(const VolumeInfo& info, const SectionSet& sections);
  std::span<const std::byte> dataBytes() const { return data_; }
  kernels::SvmmView view(const std::byte* base = nullptr) const;
  // Value ranges per 4^3 cell, dilated by one voxel, from the leaves (no full decode).
  RangeGrid rangeGrid() const;
  int format() const { return format_; }
  int levels() const { return levels_; }
  std::uint32_t flags() const { return flags_; }
  int quality() const { return quality_; }
  double delta() const { return delta_; }
  int rootWidth() const { return rootWidth_; }
  bool stepped() const { return stepped_; }
  double psnr() const { return psnr_; }
  const std::vector<int>& widths() const { return widths_; }
  // Whether level L's blocks can live in a block pool (every level but the root and a
  // block-compressed base), its pool extents, and the pool's bytes: blocks at
  // kernels::svmmPoolBlock positions of a 3D array, x fastest, unused blocks zero. A backend
  // uploads them (a CUDA 3D texture) and sets the view's level[L].pool / poolULog2 / poolVLog2.
  bool poolable(int L) const;
  kernels::SvmmPoolShape poolShape(int L) const;
  std::vector<std::uint8_t> poolBytes(int L) const;
  // Bytes per element of level L (word or base voxel).
  int elementBytes(int L) const;
  const std::vector<std::uint64_t>& blocks() const { return blocks_; }

  // Calls leaf(level, x0, y0, z0, size, value) for every terminal non-base voxel (a cube of
  // size^3 volume voxels at (x0, y0, z0), possibly past the volume's edge) and base(x, y, z,
  // value) for every voxel of every stored base block inside the volume.
  template <class Leaf, class Base>
  void forEachLeaf(Leaf&& leaf, Base&& base) const;

 private:
  // Bytes of one block of level L (the root: the whole root grid).
  std::uint64_t blockBytesOf(int L) const;
  // The constructor's steps: the params (header fields and the level table), the data section's
  // level ranges, then every sub-block offset against the running count of blocks below it.
  void readParams(const SectionSet& sections);
  ByteReader readData(const SectionSet& sections);
  void checkSubBlockOffsets(const ByteReader& data) const;

  VolumeInfo info_;
  std::uint64_t cacheId_ = 0;  // unique per opened layout: keys the CPU's decoded pages
  std::span<const std::byte> data_;
  int format_ = 1, levels_ = 1, quality_ = 100, rootWidth_ = 32, bias_ = 0;
  bool stepped_ = false;
  std::uint32_t flags_ = 0;
  double delta_ = 0, peak_ = 1, psnr_ = 0;
  glm::ivec3 root_{1, 1, 1};
  std::vector<int> widths_, shifts_;
  std::vector<std::uint64_t> blocks_, offsets_, bytes_;
};

Volume decode(const VolumeInfo& info, const SectionSet& sections);
RgbaVolume decodeRgba(const VolumeInfo& info, const SectionSet& sections);

// The Menger sponge of the thesis's evaluation as RGBA: solid voxels coloured by an RGB gradient
// over x, y, z (r = 255 x / (n - 1), ...) with alpha 255; carved voxels 0.
RgbaVolume generateMengerRgba(int level);

// PSNR over the four channels, peak 255 (+inf when equal).
double psnrRgba(const RgbaVolume& a, const RgbaVolume& b);

// The codec's registry entry (registry.hpp): the view types its payloads produce, and the codec
// object (src/svmm/registration.cpp).
struct SvmmCodecEntry {
  static constexpr CodecId kId{2};  // stored in files: never reused
  static constexpr std::string_view kName = "svmm";
  using Views = ViewList<kernels::SvmmView>;
  static const Codec& instance();
};

// ---- implementation of the template ----

template <class Leaf, class Base>
void Layout::forEachLeaf(Leaf&& leaf, Base&& base) const {
  const kernels::SvmmView v = view();
  const int top = levels_ - 1;
  const glm::ivec3 d = info_.dims;
  if (levels_ == 1) {
    for (int z = 0; z < d.z; ++z)
      for (int y = 0; y < d.y; ++y)
        for (int x = 0; x < d.x; ++x) base(x, y, z, v.baseValue(v.level[0].data, x, y, z));
    return;
  }
  // Depth-first over the tree: (level, block pointer, block origin in that level's voxels,
  // block size per side).
  auto visit = [&](auto&& self, int L, const std::uint8_t* block, glm::ivec3 origin,
                   glm::ivec3 size) -> void {
    if (L == 0) {
      const int w = size.x;
      for (int z = 0; z < w; ++z)
        for (int y = 0; y < w; ++y)
          for (int x = 0; x < w; ++x) {
            const glm::ivec3 p = origin + glm::ivec3(x, y, z);
            if (p.x < d.x && p.y < d.y && p.z < d.z)
              base(p.x, p.y, p.z, v.baseValue(block, x, y, z));
          }
      return;
    }
    const std::size_t sy = std::size_t(size.x), sz = std::size_t(size.x) * std::size_t(size.y);
    const int sh = shifts_[L];
    const int child = widths_[L - 1];
    for (int bz = 0; bz < size.z; bz += 2)
      for (int by = 0; by < size.y; by += 2)
        for (int bx = 0; bx < size.x; bx += 2) {
          const std::size_t s0 = std::size_t(bz) * sz + std::size_t(by) * sy + std::size_t(bx);
          std::uint32_t words[8], offset = 0, count = 0;
          for (int j = 0; j < 8; ++j) {
            words[j] = v.word(block, s0 + std::size_t(j & 1) + (j & 2 ? sy : 0) + (j & 4 ? sz : 0));
            offset |= (words[j] & 15u) << (4 * j);
          }
          for (int j = 0; j < 8; ++j) {
            const glm::ivec3 g =
                origin + glm::ivec3(bx + (j & 1), by + (j >> 1 & 1), bz + (j >> 2));
            if (words[j] & kernels::kSvmmTerminal) {
              leaf(L, g.x << sh, g.y << sh, g.z << sh, 1 << sh,
                   kernels::svmmWordValue(format_, words[j]));
            } else {
              const std::uint8_t* cb =
                  v.level[L - 1].data + std::size_t(offset + count) * v.level[L - 1].blockBytes;
              ++count;
              self(self, L - 1, cb, g * child, glm::ivec3(child));
            }
          }
        }
  };
  visit(visit, top, v.level[top].data, glm::ivec3(0), root_);
}

}  // namespace voxwall::codec::svmm
