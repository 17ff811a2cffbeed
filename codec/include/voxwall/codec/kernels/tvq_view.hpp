// Random access into the tvq codec's blocks (Fout and Ma, "Transform Coding for
// Hardware-Accelerated Volume Rendering", 2007), on the host or on a device. A coded 4^3 block is
// its mean plus, per partition (lowpass, bandpass, highpass), one codevector of that partition's
// *associated* codebook: a codevector already taken back through the inverse transform (the
// paper's vector reprojection, section 4.3), so a voxel is P look-ups and P - 1 additions plus
// the mean, and no block ever needs an inverse transform or a class test. The caches, corners and
// sampling are CachedBrickView's. The file layout is in tvq_codec.hpp; this is how the codec's
// Layout lays out what the view reads.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <voxwall/codec/kernels/bits.hpp>
#include <voxwall/codec/kernels/cached_brick_view.hpp>
#include <voxwall/codec/kernels/vq_view.hpp>

namespace voxwall::codec::kernels {

inline constexpr int kTvqPartitions = 3;  // lowpass, bandpass, highpass

// One sub-volume: where its codebooks, occupancy and records are, and how its records are packed.
// Each offset is in bytes from the start of its own array (TvqDecoder).
struct TvqSubvolume {
  std::uint64_t codebookAt[kTvqPartitions];  // associated codebooks: (1 + codevectors) x 64 float
  std::uint64_t occupancyAt;                 // u64 words, bit i: local block i is coded
  std::uint64_t rankAt;                      // u32 per word: coded blocks before the word
  std::uint64_t recordsAt;                   // coded blocks' records, `recordBits` each
  std::int32_t firstBlock[3];                // the sub-volume's first block per axis
  std::int32_t blocks[3];                    // its blocks per axis
  std::int32_t codeBits[kTvqPartitions];     // bits of each partition's code in a record
  std::int32_t recordBits;                   // dcBits + the three code bits
  float background;                          // the value of every voxel of an uncoded block
  std::uint32_t reserved;
};
static_assert(sizeof(TvqSubvolume) == 96);
static_assert(std::is_trivially_copyable_v<TvqSubvolume>);

// Where a host view finds a sub-volume's associated codebooks when they are made on first use
// (tvq::Layout): the start of sub-volume s's codebooks (partition p at codebookAt[p] -
// codebookAt[0] from it). Called from the render threads; never on a device.
using TvqBooksFn = const std::uint8_t* (*)(const void* owner, std::uint64_t s);

// The codec's half of the view. The arrays (host or device memory, not owned): the sub-volume
// table, the associated codebooks, the occupancy words' ranks, the occupancy words and the
// records. On the host the occupancy and records are the file's sections where they lie, and the
// codebooks come from `lazyBooks` when it is set.
struct TvqDecoder {
  static constexpr int kBrickSide = 4;
  static constexpr int kVoxels = 64;
  using Value = float;
  static constexpr std::uint64_t kUncoded = 0xFFFFFFFFull;  // the local part of an uncoded key

  const TvqSubvolume* table = nullptr;
  const std::uint8_t* books = nullptr;  // null on the host when lazyBooks is set
  const std::uint8_t* ranks = nullptr;
  const std::uint8_t* occupancy = nullptr;
  const std::uint8_t* records = nullptr;
  TvqBooksFn lazyBooks = nullptr;
  const void* lazyOwner = nullptr;
  int subvolumeBlocks = 64;  // a sub-volume's side in blocks
  int subvolumesX = 1, subvolumesY = 1;
  int dcBits = 8;
  float dcLo = 0, dcStep = 1;       // a block's mean is dcLo + q x dcStep
  float lo = 0, hi = 0;             // the volume's value range: decoded voxels are clamped to it
  int partitions = kTvqPartitions;  // progressive level: partitions added to the mean (0..3)
  bool integral = false;            // integer data: decoded voxels round to integers

  VOXWALL_HD_INLINE const TvqSubvolume& subvolume(std::uint64_t s) const { return table[s]; }

  // The sub-volume in the high 32 bits; in the low 32 the block's record among the sub-volume's
  // coded blocks, or kUncoded for a block that is the sub-volume's background.
  VOXWALL_HD_INLINE std::uint64_t key(int bx, int by, int bz) const {
    const int n = subvolumeBlocks;
    const int sx = bx / n, sy = by / n, sz = bz / n;
    const std::uint64_t s = (std::uint64_t(sz) * std::uint64_t(subvolumesY) + std::uint64_t(sy)) *
                                std::uint64_t(subvolumesX) +
                            std::uint64_t(sx);
    const TvqSubvolume& sv = subvolume(s);
    const std::uint64_t local =
        (std::uint64_t(bz - sv.firstBlock[2]) * std::uint64_t(sv.blocks[1]) +
         std::uint64_t(by - sv.firstBlock[1])) *
            std::uint64_t(sv.blocks[0]) +
        std::uint64_t(bx - sv.firstBlock[0]);
    const std::uint64_t word =
        reinterpret_cast<const std::uint64_t*>(occupancy + sv.occupancyAt)[local >> 6];
    const std::uint64_t bit = std::uint64_t(1) << (local & 63);
    if (!(word & bit)) return (s << 32) | kUncoded;
    const std::uint32_t before =
        reinterpret_cast<const std::uint32_t*>(ranks + sv.rankAt)[local >> 6];
    return (s << 32) | std::uint64_t(before + popcount64(word & (bit - 1)));
  }

  // `bits` bits from bit `bit` of p, LSB first, reading only the bytes they lie in (a record may
  // end a section that the file maps).
  static VOXWALL_HD_INLINE std::uint32_t field(const std::uint8_t* p, std::uint64_t bit, int bits) {
    const std::uint8_t* q = p + (bit >> 3);
    const int shift = int(bit & 7);
    const int bytes = (shift + bits + 7) >> 3;
    std::uint64_t word = 0;
    for (int i = 0; i < bytes; ++i) word |= std::uint64_t(q[i]) << (8 * i);
    return std::uint32_t((word >> shift) & ((std::uint64_t(1) << bits) - 1));
  }

  // The codes of record `r` of sub-volume `sv`: the quantized mean and one code per partition.
  VOXWALL_HD_INLINE void codes(const TvqSubvolume& sv, std::uint64_t r, std::uint32_t& dc,
                               std::uint32_t* k) const {
    const std::uint8_t* p = records + sv.recordsAt;
    std::uint64_t bit = r * std::uint64_t(sv.recordBits);
    dc = field(p, bit, dcBits);
    bit += std::uint64_t(dcBits);
    for (int q = 0; q < kTvqPartitions; ++q) {
      k[q] = field(p, bit, sv.codeBits[q]);
      bit += std::uint64_t(sv.codeBits[q]);
    }
  }

  // Record `key`'s quantized mean and the associated codevector of each partition the
  // progressive level keeps (v[0] .. v[partitions - 1], 64 floats each); false for an uncoded
  // block. The page decoder asks for the codevectors of bricks ahead through this too.
  VOXWALL_HD_INLINE bool codevectors(std::uint64_t key, std::uint32_t& dc,
                                     const float* (&v)[kTvqPartitions]) const {
    const TvqSubvolume& sv = subvolume(key >> 32);
    const std::uint64_t r = key & 0xFFFFFFFFull;
    if (r == kUncoded) return false;
    std::uint32_t k[kTvqPartitions];
    codes(sv, r, dc, k);
    const std::uint8_t* base = books;
    std::uint64_t first = 0;
#if !defined(__CUDA_ARCH__)
    if (lazyBooks) base = lazyBooks(lazyOwner, key >> 32), first = sv.codebookAt[0];
#endif
    for (int p = 0; p < partitions; ++p)
      v[p] = reinterpret_cast<const float*>(base + (sv.codebookAt[p] - first)) +
             std::size_t(k[p]) * std::size_t(kVoxels);
    return true;
  }

  // Equation 6 of the paper: the mean plus the associated codevector of each partition the
  // progressive level keeps, clamped to the volume's range.
  VOXWALL_HD_INLINE void decode(std::uint64_t key, float* out) const {
    std::uint32_t dc = 0;
    const float* v[kTvqPartitions];
    if (!codevectors(key, dc, v)) {
      const float background = subvolume(key >> 32).background;
      for (int i = 0; i < kVoxels; ++i) out[i] = background;
      return;
    }
    const float mean = dcLo + float(dc) * dcStep;
    for (int i = 0; i < kVoxels; ++i) out[i] = mean;
    for (int p = 0; p < partitions; ++p)
      for (int i = 0; i < kVoxels; ++i) out[i] += v[p][i];
    // Written so that a NaN (which a validated file cannot make) would become `lo` too. Integer
    // data is rounded here, so the view samples exactly the decoded volume's values.
    for (int i = 0; i < kVoxels; ++i) {
      const float v = integral ? floorf(out[i] + 0.5f) : out[i];
      out[i] = v >= lo ? (v <= hi ? v : hi) : lo;
    }
  }

  VOXWALL_HD_INLINE float scalar(float v) const { return v; }
};

using TvqView = CachedBrickView<TvqDecoder>;

static_assert(std::is_trivially_copyable_v<TvqView>);

}  // namespace voxwall::codec::kernels
