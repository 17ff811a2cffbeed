// The `zfp` codec: the volume cut into bricks of 16^3 voxels, each brick compressed on its own by
// the zfp library (Lindstrom, "Fixed-Rate Compressed Floating-Point Arrays", 2014; Diffenderfer et
// al., "Error Analysis of ZFP Compression for Floating-Point Data", 2019) in one of its modes, with
// an index of where each brick's stream starts, so a renderer decodes any brick alone.
//
// Every scalar type goes through zfp's float path (integers are exact in a float); a decoded value
// is clamped to the input's value range (lo, hi below) and, for integer types, rounded.
// A brick whose zfp stream would be larger than its voxels stored as they are is stored as they
// are: no file is larger than the raw data plus the index (at most 4 bytes per brick, 8 per row of
// bricks) and the headers.
//
// Sections (ids within the codec's own, ZfpCodecEntry::kId):
//   1 params (72 bytes, little-endian):
//       u32 mode (1 fixed accuracy, 2 fixed precision, 3 fixed rate, 4 reversible)
//       u32 minbits, u32 maxbits, u32 maxprec, i32 minexp   (zfp's expert parameters: together
//           they are the mode; a reader sets them with zfp_stream_set_params)
//       u32 entry bits W (2..32: the index's bits per brick; 0 in files from before the entries
//           were packed, which have a u32 each, as W = 32)
//       f64 setting (the tolerance, precision or rate asked for; 0 for reversible)
//       f64 psnr of the decoded volume against the input, dB (+inf when equal)
//       f64 max error (the largest |decoded - input| over every voxel)
//       u64 stored bricks (bricks kept as they are)
//       f64 lo, f64 hi (the input's smallest and largest value: finite, lo <= hi)
//   2 index: for the R = bricksY x bricksZ rows of bricks along x, R + 1 u64: the bit at which
//       each row starts in `stream` (the first 0, the last the stream's length in bits, each at
//       most 2^31 - 1 bits after the one before); then for each brick (x fastest) an entry of W
//       bits, packed LSB first with no padding between them (the section ends with the byte that
//       holds the last entry's last bit): its top bit set when the brick is stored as it is, the
//       W - 1 bits below it where the brick starts, in bits after its row's start. The encoder
//       writes the narrowest W that holds the largest such offset. A brick ends where the next
//       one of its row starts, the last one where the next row does.
//   3 stream: the bricks' bits back to back, LSB first in little-endian 64-bit words (zfp's bit
//       stream), padded with zeros to a whole word: each brick either zfp's stream of its
//       nx x ny x nz voxels (nx = min(16, dimX - 16 bx), ...), its 4^3 blocks in zfp_compress's
//       order with no padding, or those voxels in the volume's scalar type, x fastest.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/zfp_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::zfp {

enum SectionId : std::uint32_t { kParams = 1, kIndex = 2, kStream = 3 };
enum class Mode : std::uint32_t { Accuracy = 1, Precision = 2, Rate = 3, Reversible = 4 };
std::string_view modeName(Mode mode);  // "fixed accuracy", ...

struct Params {
  Mode mode = Mode::Accuracy;
  double tolerance = 0;           // fixed accuracy: the largest error; 0: the value range / 64
  int precision = 16;             // fixed precision: bit planes kept (1..32)
  double rate = 4;                // fixed rate: bits per voxel of each block (0.25 .. 32)
  double targetBitsPerVoxel = 0;  // > 0: fixed accuracy with the tolerance that meets this size
  int threads = 0;                // 0: every usable core
};

// What the encoder did, for the CLI and benchmarks.
struct EncodeStats {
  Mode mode = Mode::Accuracy;
  double setting = 0;  // the tolerance, precision or rate used
  std::uint64_t bricks = 0, storedBricks = 0;
  std::uint64_t streamBytes = 0, indexBytes = 0;
  double bitsPerVoxel = 0;  // of the whole file's sections
  double psnr = 0, maxError = 0;
  int searchSteps = 0;  // encodings of the sample the size target took
};

// Throws std::invalid_argument for bad parameters, float data that is not finite, or a size
// target the codec cannot reach on this volume (the message says what it can reach).
CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);
// The same from a volume read a row of bricks (16 slices) at a time: the same bytes.
CompressedVolume encode(const VolumeSource& source, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);

struct Index;  // src/zfp/format.hpp

// The sections of a zfp-coded volume, validated against the header: params, every index entry
// and every brick's length. Throws FormatError naming the source and the section.
class Layout {
 public:
  Layout(const VolumeInfo& info, const SectionSet& sections);
  // The host view (the index and the stream where they lie).
  kernels::ZfpView view() const;
  // Value ranges per brick, dilated by one voxel.
  RangeGrid rangeGrid() const;
  Mode mode() const { return mode_; }
  double setting() const { return setting_; }
  double psnr() const { return psnr_; }
  double maxError() const { return maxError_; }
  std::uint64_t storedBricks() const { return storedBricks_; }
  std::uint64_t streamBytes() const { return stream_.size(); }

 private:
  void readParams(const SectionSet& sections);
  void checkIndex(const SectionSet& sections);
  Index index() const;

  VolumeInfo info_;
  std::span<const std::byte> params_, index_, stream_;
  Mode mode_ = Mode::Accuracy;
  kernels::ZfpStreamParams zfp_;
  double setting_ = 0, psnr_ = 0, maxError_ = 0, lo_ = 0, hi_ = 0;
  std::uint64_t bricks_ = 0, rows_ = 0, storedBricks_ = 0;
  int entryBits_ = 32;
  std::uint64_t cacheId_ = 0;  // unique per Layout: keys the views' decoded-brick caches
};

// Full reconstruction, in the volume's scalar type.
Volume decode(const VolumeInfo& info, const SectionSet& sections);

// The codec's registry entry (registry.hpp): the view types its payloads produce, and the codec
// object (src/zfp/registration.cpp).
struct ZfpCodecEntry {
  static constexpr CodecId kId{6};  // stored in files: never reused
  static constexpr std::string_view kName = "zfp";
  using Views = ViewList<kernels::ZfpView>;  // and raw's views, on a device
  static const Codec& instance();
};

}  // namespace voxwall::codec::zfp
