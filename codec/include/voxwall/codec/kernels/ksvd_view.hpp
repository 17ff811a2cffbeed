// Random access into the ksvd codec's blocks (Gobbetti, Iglesias Guitian and Marton, COVRA,
// 2012), on the host or on a device: a block is the sum over its (atom, coefficient) pairs of
// coefficient x atom, plus its brick's minimum, clamped to the brick's range. The caches, corners
// and sampling of one level are CachedBrickView's; KsvdView adds the pyramid of levels (each
// half the resolution of the one before) that `render --lod` reads. The file layout is
// documented in ksvd_codec.hpp; this is the layout of the render buffer the codec's Layout
// builds from it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <voxwall/codec/kernels/bits.hpp>
#include <voxwall/codec/kernels/cached_brick_view.hpp>
#include <voxwall/codec/kernels/view_concept.hpp>

namespace voxwall::codec::kernels {

// One brick of the render buffer: its value range, the coefficient step (0: a constant brick,
// every voxel `lo`), its index among the coded bricks (its blocks' means are row `coded` of the
// dc stream), the index of its first pair and the bit where its blocks' unary pair counts start.
struct KsvdBrick {
  float lo = 0, hi = 0, step = 0;
  std::uint32_t coded = 0;
  std::uint64_t firstPair = 0;
  std::uint64_t countBit = 0;
};
static_assert(sizeof(KsvdBrick) == 32);

// A packed bit stream of `bytes` bytes, LSB-first; reads past its end give zero bits.
struct KsvdBits {
  const std::uint8_t* data = nullptr;
  std::uint64_t bytes = 0;

  // `width` (<= 25) bits from bit `bit`; reads only the bytes they lie in.
  VOXWALL_HD_INLINE std::uint32_t field(std::uint64_t bit, int width) const {
    const std::uint64_t at = bit / 8;
    const int shift = int(bit % 8), n = (shift + width + 7) / 8;  // <= 4
    std::uint32_t word = 0;
    for (int b = 0; b < n; ++b)
      if (at + std::uint64_t(b) < bytes)
        word |= std::uint32_t(data[at + std::uint64_t(b)]) << (8 * b);
    return (word >> shift) & ((1u << width) - 1u);
  }
  // The 64 bits from bit `bit`.
  VOXWALL_HD_INLINE std::uint64_t word64(std::uint64_t bit) const {
    const std::uint64_t at = bit / 8;
    const int shift = int(bit % 8);
    std::uint64_t lo = 0, hi = 0;
    if (at + 9 <= bytes) {
      for (int b = 0; b < 8; ++b) lo |= std::uint64_t(data[at + std::uint64_t(b)]) << (8 * b);
      hi = data[at + 8];
    } else {
      for (int b = 0; b < 8; ++b)
        if (at + std::uint64_t(b) < bytes)
          lo |= std::uint64_t(data[at + std::uint64_t(b)]) << (8 * b);
      if (at + 8 < bytes) hi = data[at + 8];
    }
    return shift ? (lo >> shift) | (hi << (64 - shift)) : lo;
  }
  // Unary codes from bit `first`: each a run of ones (its value) ended by a zero. Sets `start`
  // to where code j begins (past j zeros) and returns its value.
  VOXWALL_HD_INLINE int unary(std::uint64_t first, int j, std::uint64_t& start) const {
    std::uint64_t at = first;
    for (int skip = j; skip > 0;) {
      const std::uint64_t ends = ~word64(at);  // a one where a code ends
      const int n = popcount64(ends);
      if (n < skip) {
        skip -= n, at += 64;
        continue;
      }
      std::uint64_t m = ends;
      for (int k = 1; k < skip; ++k) m &= m - 1;
      at += std::uint64_t(trailingZeros64(m) + 1);
      break;
    }
    start = at;
    int value = 0;
    for (;;) {
      const int ones = trailingZeros64(~word64(at));
      value += ones;
      if (ones < 64) return value;
      at += 64;
    }
  }
};

// The pair of width indexBits + coefBits (<= 24) at bit `bit` of a pair stream: the atom index in
// its low indexBits bits, the quantized coefficient (two's complement) in the coefBits above.
VOXWALL_HD_INLINE void ksvdUnpackAt(const KsvdBits& stream, std::uint64_t bit, int indexBits,
                                    int coefBits, int& atom, int& q) {
  const std::uint32_t word = stream.field(bit, indexBits + coefBits);
  atom = int(word & ((1u << indexBits) - 1u));
  const std::uint32_t sign = 1u << (coefBits - 1);
  q = int((word >> indexBits) ^ sign) - int(sign);  // sign-extends coefBits bits
}

// Pair `index` of a pair stream of indexBits + coefBits bits a pair, LSB-first (the file's pairs
// section; files from before the width was stored hold 3-byte pairs: coefBits = 24 - indexBits).
// Reads only the bytes the pair lies in.
VOXWALL_HD_INLINE void ksvdUnpack(const std::uint8_t* stream, std::uint64_t index, int indexBits,
                                  int coefBits, int& atom, int& q) {
  const KsvdBits bits{stream, ~std::uint64_t(0)};
  ksvdUnpackAt(bits, index * std::uint64_t(indexBits + coefBits), indexBits, coefBits, atom, q);
}

// The codec's half of the view of one level, for blocks of Side^3 voxels. `data` is the render
// buffer:
//   atoms (K x Side^3 float, atom-major) at atomsAt,
//   the level's bricks (KsvdBrick per brick, x fastest) at bricksAt.
// Offsets are multiples of 8 bytes; the buffer points into host or device memory, not owned.
// Three bit streams (every level's; on the host the file's sections where they lie, their pages
// come in where rays go; on a device after the buffer):
//   `dc`: per coded brick and block, its mean above the brick's minimum in dcBits bits, in steps
//       of (max - min) / (2^dcBits - 1) (dcBits 0: no stream, the mean is 0: files of layout 1,
//       whose means are pairs of the DC atom);
//   `counts`: per coded brick and block, its number of pairs in unary;
//   `pairs`: the pairs, indexBits + coefBits bits each (ksvdUnpackAt).
// A block's pairs start at its brick's firstPair plus the counts of the brick's blocks before
// it, which the unary codes give by counting bits (no table per block).
// Keys are block indices plus keyBase (the blocks of the levels before), so the blocks of
// different levels never share a key in the block cache.
template <int Side>
struct KsvdDecoder {
  static constexpr int kBrickSide = Side;
  static constexpr int kVoxels = Side * Side * Side;
  using Value = float;

  const std::uint8_t* data = nullptr;
  KsvdBits pairs, counts, dc;
  std::uint64_t atomsAt = 0, bricksAt = 0;
  int blocksX = 0, blocksY = 0;
  int bricksX = 0, bricksY = 0;
  int blocksPerBrick = 1;  // N: bricks are N^3 blocks
  int indexBits = 10, coefBits = 14;
  int dcBits = 0;
  float dcLevels = 1.0f;  // 2^dcBits - 1
  std::uint64_t keyBase = 0;
  bool integral = false;  // integer data: decoded voxels round to integers

  VOXWALL_HD_INLINE std::uint64_t key(int bx, int by, int bz) const {
    return keyBase +
           (std::uint64_t(bz) * std::uint64_t(blocksY) + std::uint64_t(by)) *
               std::uint64_t(blocksX) +
           std::uint64_t(bx);
  }

  // Where block `key`'s code is: its brick's record, its mean above the brick's minimum, its
  // first pair and its pair count (0 for a constant brick, every voxel `brick.lo`).
  struct BlockCode {
    KsvdBrick brick;
    std::uint64_t firstPair;  // in the pair stream
    float dc;
    int count;
  };
  VOXWALL_HD_INLINE BlockCode locate(std::uint64_t key) const {
    const std::uint64_t block = key - keyBase;
    const int bx = int(block % std::uint64_t(blocksX));
    const std::uint64_t rest = block / std::uint64_t(blocksX);
    const int by = int(rest % std::uint64_t(blocksY)), bz = int(rest / std::uint64_t(blocksY));
    const int n = blocksPerBrick;
    const std::uint64_t brickIndex =
        (std::uint64_t(bz / n) * std::uint64_t(bricksY) + std::uint64_t(by / n)) *
            std::uint64_t(bricksX) +
        std::uint64_t(bx / n);
    BlockCode code;
    code.brick = reinterpret_cast<const KsvdBrick*>(data + bricksAt)[brickIndex];
    code.firstPair = 0, code.dc = 0.0f, code.count = 0;
    if (code.brick.step == 0.0f) return code;
    const int j = ((bz % n) * n + by % n) * n + bx % n;
    const std::uint64_t perBrick = std::uint64_t(n * n * n);
    if (dcBits > 0) {
      const std::uint32_t q = dc.field(
          (std::uint64_t(code.brick.coded) * perBrick + std::uint64_t(j)) * std::uint64_t(dcBits),
          dcBits);
      code.dc = float(q) * ((code.brick.hi - code.brick.lo) / dcLevels);
    }
    std::uint64_t start = 0;
    code.count = counts.unary(code.brick.countBit, j, start);
    code.firstPair = code.brick.firstPair + (start - code.brick.countBit - std::uint64_t(j));
    return code;
  }
  // A decoded voxel: the brick's minimum plus the sum of the pairs' contributions, clamped to
  // the brick's range; written so that a NaN (a hostile file's overflowing sum) becomes the
  // brick's minimum too.
  VOXWALL_HD_INLINE float finish(const KsvdBrick& brick, float sum) const {
    // Integer data is rounded here, so the view samples exactly the decoded volume's values.
    const float v = integral ? floorf(brick.lo + sum + 0.5f) : brick.lo + sum;
    return v >= brick.lo ? (v <= brick.hi ? v : brick.hi) : brick.lo;
  }

  // COVRA's two-phase decode of one block (section 5.2), as the device decompressor runs it
  // with a thread per pair and then a thread per voxel, a barrier between the phases:
  // phase 1, pair t (< code.count) of the block, dequantized;
  VOXWALL_HD_INLINE void pairOf(const BlockCode& code, int t, int& atom, float& coefficient) const {
    int q = 0;
    ksvdUnpackAt(pairs, (code.firstPair + std::uint64_t(t)) * std::uint64_t(indexBits + coefBits),
                 indexBits, coefBits, atom, q);
    coefficient = float(q) * code.brick.step;
  }
  // phase 2, voxel v (< Side^3): the block's mean plus its pairs (as pairOf gave them), summed in
  // pair order like decode().
  VOXWALL_HD_INLINE float voxelOf(const BlockCode& code, const int* atom, const float* coefficient,
                                  int v) const {
    const float* atomValues = reinterpret_cast<const float*>(data + atomsAt);
    float sum = code.dc;
    for (int k = 0; k < code.count; ++k)
      sum += coefficient[k] * atomValues[std::size_t(atom[k]) * kVoxels + std::size_t(v)];
    return finish(code.brick, sum);
  }

  VOXWALL_HD_INLINE void decode(std::uint64_t key, float* out) const {
    const BlockCode code = locate(key);
    const float* atomValues = reinterpret_cast<const float*>(data + atomsAt);
    for (int i = 0; i < kVoxels; ++i) out[i] = code.dc;
    for (int k = 0; k < code.count; ++k) {
      int atom = 0;
      float c = 0.0f;
      pairOf(code, k, atom, c);
      const float* a = atomValues + std::size_t(atom) * kVoxels;
      for (int i = 0; i < kVoxels; ++i) out[i] += c * a[i];
    }
    for (int i = 0; i < kVoxels; ++i) out[i] = finish(code.brick, out[i]);
  }

  VOXWALL_HD_INLINE float scalar(float v) const { return v; }
};

// The most levels a ksvd file holds (the view carries one level view each).
constexpr int kKsvdMaxLevels = 8;

// The view of a ksvd volume: a pyramid of levels, level l of ((dim - 1) >> l) + 1 voxels per
// axis, voxel centres at (index + 1/2) 2^l - 1/2 in the full-resolution index space. With
// kTraversal the raycaster sets the ray's footprint (voxels per pixel) and the sampling mode:
// a sample reads the coarsest level whose voxels are at most the footprint wide, trilinear or
// nearest. No region is reported (regionValid stays false): the range grid's empty-space
// skipping is all the skipping a ksvd volume gets.
template <int Side>
struct KsvdView {
  static constexpr bool kTraversal = true;
  using Level = CachedBrickView<KsvdDecoder<Side>>;
  Level level[kKsvdMaxLevels];
  int levels = 1;
  int dimX = 0, dimY = 0, dimZ = 0;  // level 0's

  struct RayCache {
    typename Level::RayCache inner;
    int il = -1;  // the level `inner` holds the bricks and cell of
    float footprint = 0.0f;
    bool nearest = false;
    bool regionValid = false;
    float regionLo[3] = {0.0f, 0.0f, 0.0f}, regionHi[3] = {0.0f, 0.0f, 0.0f};
    float regionFootprintMax = 3.0e38f;
  };

  // The level whose voxels are at most `footprint` voxels wide (0 below 2).
  VOXWALL_HD_INLINE int lodLevel(float footprint) const {
    int L = 0;
    while (L + 1 < levels && float(2 << L) <= footprint) ++L;
    return L;
  }

  // Switches the ray's cache to level L: the cell and the memo of the level before name
  // other bricks (the cached blocks themselves are keyed per level and stay).
  VOXWALL_HD_INLINE void enter(int L, RayCache& rc) const {
    if (L == rc.il) return;
    rc.il = L;
    rc.inner.ix = -1;
    rc.inner.grad.ix = -1;
#if !defined(__CUDA_ARCH__)
    rc.inner.memoWrites = ~0ull;
#endif
  }

  // A full-resolution index-space position as a position on level L's grid.
  static VOXWALL_HD_INLINE void toLevel(int L, float& x, float& y, float& z) {
    if (L == 0) return;
    const float s = 1.0f / float(1 << L);
    x = (x + 0.5f) * s - 0.5f, y = (y + 0.5f) * s - 0.5f, z = (z + 0.5f) * s - 0.5f;
  }

  VOXWALL_HD_INLINE float sample(float x, float y, float z, RayCache& rc) const {
    const int L = rc.footprint >= 2.0f ? lodLevel(rc.footprint) : 0;
    enter(L, rc);
    rc.regionFootprintMax = L + 1 < levels ? float(2 << L) : 3.0e38f;
    toLevel(L, x, y, z);
    const Level& v = level[L];
    if (rc.nearest) {
      x = clampPosition(x, v.maxX), y = clampPosition(y, v.maxY), z = clampPosition(z, v.maxZ);
      return v.voxel(int(x + 0.5f), int(y + 0.5f), int(z + 0.5f), rc.inner);
    }
    return v.sample(x, y, z, rc.inner);
  }
  VOXWALL_HD_INLINE float sample(float x, float y, float z) const {
    RayCache rc;
    return sample(x, y, z, rc);
  }

  // A gradient neighbour, on the level of the ray's last sample.
  VOXWALL_HD_INLINE float sampleNear(float x, float y, float z, RayCache& rc) const {
    const int L = rc.il < 0 ? 0 : rc.il;
    enter(L, rc);
    toLevel(L, x, y, z);
    return level[L].sampleNear(x, y, z, rc.inner);
  }

  // The gradient hook, on full-resolution trilinear samples only: a coarser level's or a nearest
  // sample's gradient stays the six samples it always was.
  VOXWALL_HD_INLINE bool gradient(float x, float y, float z, RayCache& rc, float* g) const {
    if (rc.il != 0 || rc.nearest) return false;
    return level[0].gradient(x, y, z, rc.inner, g);
  }

  VOXWALL_HD_INLINE float voxel(int x, int y, int z) const { return level[0].voxel(x, y, z); }

  // What the CPU's decoded pages hold (node/page_cache.hpp): level 0, and under pressure level 1,
  // whose voxels are 2 of level 0's a side (only where levels > 1).
  const Level& pagedLevel() const { return level[0]; }
  const Level& coarsePages() const { return level[1]; }
  float coarseScale() const { return 2.0f; }
};

using KsvdView4 = KsvdView<4>;
using KsvdView6 = KsvdView<6>;
using KsvdView8 = KsvdView<8>;

static_assert(std::is_trivially_copyable_v<KsvdView6>);
static_assert(TraversalView<KsvdView6>);

}  // namespace voxwall::codec::kernels
