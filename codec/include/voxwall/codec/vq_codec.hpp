// The `vq` codec (Guthe & Goesele, "Variable Length Coding for GPU-Based Direct Volume
// Rendering", sections 3-5).
//
// The volume is cut into 4^3 bricks (the border padded by repeating the edge voxel). Equal bricks
// are stored once, in a *codebook*; an *offset volume* of ceil(X/4) x ceil(Y/4) x ceil(Z/4)
// entries says which codeword each brick is. Lossless by default; with a reduction the unique
// bricks are clustered by weighted k-means into 1/K as many codewords (vq_kmeans.hpp).
//
// Values are coded as unsigned integers of `bits` bits (8, 12 or 16): uint8 data is 8-bit;
// uint16 and int16 data are 12-bit when their value range spans fewer than 4096 values, else
// 16-bit; int16 data is shifted by `bias` (its minimum) to be non-negative. float32 is refused.
//
// Sections (ids within the codec's own, VqCodecEntry::kId):
//   1 params (little-endian):
//       u32 bits (8, 12, 16)          i32 bias (added to every decoded value)
//       u32 flags: bit 0 compressed codebook, bit 1 indirect mapping, bit 2 shared book
//       u32 offsetBits (bits per offset-volume entry, 1..57)
//       u32 addressBits (bits per index-table entry, 0 unless indirect, else 1..57)
//       u32 reduction (K of --reduction, 1 for lossless)
//       u64 codewords
//       u64 indexTableAt, u64 codebookAt, u64 codebookBytes (byte offsets/sizes in `data`, or
//           in `book` with a shared book)
//       f64 psnr of the decoded volume against the input in dB (+inf when lossless)
//   2 data: the offset volume (entries bit-packed LSB first, bricks x fastest), then the index
//       table, then the codebook; each array starts at a multiple of 64 bytes and is followed by
//       at least 8 zero bytes (the decoders read 8 bytes at a time).
//   3 book (with flag bit 2 only): the index table and the codebook, laid out as in `data`;
//       `data` then holds the offset volume alone. A time series coded with one codebook
//       (encodeSeries) has a book every step shares, stored once in the file, and its own
//       params (its PSNR) and offset volume per step.
//
// An offset-volume entry is the codeword's index (plain codebook; compressed codebook with
// indirect mapping, where the index table maps it to a byte address) or the codeword's byte
// address in the codebook (compressed codebook, direct mapping). Direct or indirect is chosen
// by the smaller size (section 3.2): direct ceil(N b / 8) bytes, indirect ceil(N a / 8) +
// ceil(M b / 8) bytes for N bricks, M codewords, a index bits and b address bits.
//
// Plain codeword: 64 values x fastest, `bits` bits each, LSB first (8 * bits bytes).
// Compressed codeword (RBUC, section 3.1), byte-aligned throughout:
//   min and max of the brick, `bits` bits each, in ceil(2 bits / 8) bytes;
//   if min == max, nothing more (a constant brick). Otherwise one header byte:
//     255: escape, followed by the 64 values as in a plain codeword;
//     else c2 (bits per c1 value, 0..5) in the low 6 bits and the transformation id (0..3) in
//     the high 2 bits, then c2 bytes holding c1(0..7) with c2 bits each, then for each group
//     i = 0..7, c1(i) bytes holding c0(8i .. 8i + 7) with c1(i) bits each.
//   c0 is the brick's values minus min (transformation 0) or the zigzag-coded residual against
//   a prediction from earlier voxels (transformations 1-3; kernels::vqPredict). The encoder
//   picks the transformation that gives the shortest codeword, and the escape when even that is
//   longer than the plain values.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/vq_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::vq {

enum SectionId : std::uint32_t { kParams = 1, kData = 2, kBook = 3 };
enum Flags : std::uint32_t { kCompressed = 1, kIndirect = 2, kSharedBook = 4 };

struct Params {
  int reduction = 1;               // keep 1/K of the unique bricks: 1 (lossless) or 2..1024
  double targetBitsPerVoxel = 0;   // > 0: choose the reduction for this rate instead
  bool compressedCodebook = true;  // RBUC codebook (false: plain bit-packed codewords)
  int maxIterations = 50;          // k-means iterations at most
  int threads = 0;                 // 0: every usable core
};

// What the encoder did, for the CLI and benchmarks.
struct EncodeStats {
  std::uint64_t bricks = 0, uniqueBricks = 0, codewords = 0;
  int reduction = 1;
  double psnr = 0;  // decoded against the input, dB (+inf when lossless)
  bool indirect = false;
  std::uint64_t offsetVolumeBytes = 0, indexTableBytes = 0, codebookBytes = 0;
  // Compressed codewords stored raw, and per transformation (constant bricks are in neither).
  std::uint64_t escapes = 0;
  std::uint64_t transformUse[4] = {};
  // k-means (zero when lossless)
  int iterations = 0;
  std::uint64_t distancesComputed = 0, distancesSkipped = 0, plainEquivalent = 0;
  double kmeansSeconds = 0;
};

// Throws std::invalid_argument for float data or bad parameters.
CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);
// The same from a volume read a row of bricks (4 slices) at a time: the same bytes. What stays
// in memory is the unique bricks (the lossless codebook, or k-means' input) and 4 bytes per brick.
CompressedVolume encode(const VolumeSource& volume, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);

// A time series with one codebook for every step: the steps stacked along z (each padded to
// whole bricks) are coded as one volume (lossless, or reduced by k-means over the unique bricks
// of every step), then cut into steps that share the index table and codebook (section `book`).
// `stats` (optional) gets one entry a step: bricks, codewords and bytes of the shared book, and
// the step's PSNR. Throws as encode() does.
CompressedSeries encodeSeries(const SeriesSource& series, const Params& params, Progress& progress,
                              std::vector<EncodeStats>* stats = nullptr);

// Data bit depth the codec uses for a volume (8, 12 or 16) and its bias.
int bitDepth(const Volume& volume);

// ---- building blocks, exposed for tests -------------------------------------------------

// One brick's 64 unsigned values, x fastest.
using Brick = std::array<std::uint16_t, kernels::kVqBrickVoxels>;

// RBUC-codes a brick (values < 2^bits) with transformation `transform` (0..3), or with the
// best one when transform < 0. Appends to `out` and returns the transformation used, or
// kernels::kVqEscape for a raw brick, or -1 for a constant brick.
int encodeCodeword(const Brick& brick, int bits, std::vector<std::uint8_t>& out,
                   int transform = -1);
// Largest size of a compressed codeword: min/max, header byte and the raw values.
inline std::size_t maxCodewordBytes(int bits) {
  return std::size_t((2 * bits + 7) / 8 + 1 + 8 * bits);
}
// Length of the codeword at `p` (at most `available` bytes; 8 more bytes must be readable, as
// the padding after a codebook guarantees); throws FormatError naming `source` when it is
// malformed or runs past `available`.
std::size_t codewordLength(const std::uint8_t* p, std::size_t available, int bits,
                           const std::string& source);

// Bits needed for values 0..maxValue (at least 1).
int bitsFor(std::uint64_t maxValue);
// Direct (false) or indirect (true) mapping by the size formula of section 3.2.
bool chooseIndirect(std::uint64_t entries, std::uint64_t codewords, std::uint64_t codebookBytes);

// The sections of a vq-coded volume, validated against the header: params, array bounds, every
// offset-volume entry and every codeword. Throws FormatError naming the source and the section.
class Layout {
 public:
  Layout(const VolumeInfo& info, const SectionSet& sections);
  std::span<const std::byte> dataBytes() const { return data_; }
  // Whether the index table and codebook are in a book of their own (a series' shared one).
  bool sharedBook() const { return flags_ & kSharedBook; }
  // What a device backend uploads: dataBytes(), or with a shared book the data and the book in
  // one buffer (the book at deviceBookAt()).
  std::vector<std::byte> joinedBytes() const;
  std::uint64_t deviceBookAt() const;
  // The view with its data at `base` (host memory by default, or a device copy of dataBytes(),
  // or of joinedBytes() with a shared book).
  kernels::VqView view(const std::byte* base = nullptr) const;
  // Value ranges per 4^3 brick, dilated by one brick (a superset of the one-voxel dilation).
  RangeGrid rangeGrid() const;
  int bits() const { return bits_; }
  std::uint32_t flags() const { return flags_; }
  std::uint64_t codewords() const { return codewords_; }
  int reduction() const { return reduction_; }
  double psnr() const { return psnr_; }
  std::uint64_t indexTableAt() const { return indexTableAt_; }
  std::uint64_t codebookAt() const { return codebookAt_; }
  std::uint64_t codebookBytes() const { return codebookBytes_; }

 private:
  VolumeInfo info_;
  std::span<const std::byte> data_, book_;  // book_ == data_ unless the book is shared
  int bits_ = 8, bias_ = 0, offsetBits_ = 1, addressBits_ = 0, reduction_ = 1;
  std::uint32_t flags_ = 0;
  std::uint64_t codewords_ = 0, indexTableAt_ = 0, codebookAt_ = 0, codebookBytes_ = 0;
  double psnr_ = 0;
  std::uint64_t cacheId_ = 0;  // unique per Layout: keys the views' decoded-brick caches
};

// Full reconstruction, in the volume's scalar type.
Volume decode(const VolumeInfo& info, const SectionSet& sections);

// The codec's registry entry (registry.hpp): the view types its payloads produce, and the codec
// object (src/vq/registration.cpp).
struct VqCodecEntry {
  static constexpr CodecId kId{3};  // stored in files: never reused
  static constexpr std::string_view kName = "vq";
  using Views = ViewList<kernels::VqView>;
  static const Codec& instance();
};

}  // namespace voxwall::codec::vq
