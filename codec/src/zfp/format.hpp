// What the zfp codec's encoder and reader share (private to src/zfp/): the bricks' shapes, the
// parameters of each mode, the index, and one brick's bits through libzfp.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <glm/vec3.hpp>
#include <vector>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/zfp_codec.hpp>

namespace voxwall::codec::zfp {

inline constexpr int kBrick = kernels::kZfpBrick;
inline constexpr int kBrickVoxels = kBrick * kBrick * kBrick;
inline constexpr std::size_t kParamsBytes = 72;
inline constexpr std::uint32_t kStoredFlag = 1u << 31;
inline constexpr std::uint64_t kMaxRowBits = kStoredFlag - 1;  // a brick's offset in its row

// The voxels of brick (bx, by, bz) inside a volume of `dims` (16 per axis but at the far faces).
struct BrickShape {
  int nx = kBrick, ny = kBrick, nz = kBrick;
  int voxels() const { return nx * ny * nz; }
  int blocks() const { return ((nx + 3) / 4) * ((ny + 3) / 4) * ((nz + 3) / 4); }
};
BrickShape brickShape(glm::ivec3 dims, std::uint64_t brick);
glm::ivec3 brickGrid(glm::ivec3 dims);

// The index section (zfp_codec.hpp): rows + 1 u64 bit offsets of the rows of bricks along x, then
// an entry of `entryBits` bits per brick, packed LSB first (32: one u32 each, as in files from
// before the width was stored). Reads host memory; the Layout has checked it.
struct Index {
  const std::uint8_t* at = nullptr;
  std::uint64_t rows = 0, bricksX = 0;
  int entryBits = 32;
  std::uint64_t rowBase(std::uint64_t r) const {
    std::uint64_t v;
    std::memcpy(&v, at + 8 * r, 8);
    return v;
  }
  // Brick `brick`'s entry as a u32: kStoredFlag when stored, its offset in its row below it.
  std::uint32_t entry(std::uint64_t brick) const {
    const std::uint8_t* entries = at + 8 * (rows + 1);
    if (entryBits == 32) {
      std::uint32_t v;
      std::memcpy(&v, entries + 4 * brick, 4);
      return v;
    }
    // The bytes that hold the entry's bits only: the section ends with the last entry's byte.
    const std::uint64_t bit = brick * std::uint64_t(entryBits);
    const int shift = int(bit % 8), bytes = (shift + entryBits + 7) / 8;
    std::uint64_t word = 0;
    for (int i = 0; i < bytes; ++i)
      word |= std::uint64_t(entries[bit / 8 + std::uint64_t(i)]) << (8 * i);
    word >>= shift;
    const std::uint64_t offset = word & ((std::uint64_t(1) << (entryBits - 1)) - 1);
    return std::uint32_t(offset) | ((word >> (entryBits - 1)) & 1 ? kStoredFlag : 0);
  }
  bool stored(std::uint64_t brick) const { return entry(brick) & kStoredFlag; }
  std::uint64_t begin(std::uint64_t brick) const {
    return rowBase(brick / bricksX) + (entry(brick) & ~kStoredFlag);
  }
  std::uint64_t end(std::uint64_t brick) const {
    return (brick + 1) % bricksX ? begin(brick + 1) : rowBase(brick / bricksX + 1);
  }
  static std::uint64_t bytes(std::uint64_t rows, std::uint64_t bricks, int entryBits) {
    return 8 * (rows + 1) + (bricks * std::uint64_t(entryBits) + 7) / 8;
  }
  // The narrowest entry for offsets up to `largestOffset` (the stored flag above them): 2..32.
  static int bitsFor(std::uint64_t largestOffset) {
    int bits = 1;
    while (bits < 31 && (largestOffset >> bits)) ++bits;
    return bits + 1;
  }
};

// zfp's expert parameters of a mode: `setting` is the tolerance, precision or rate (unused for
// reversible). Throws std::invalid_argument when zfp refuses them.
kernels::ZfpStreamParams streamParams(Mode mode, double setting);
// The mode zfp sees in `params` (Mode{0} when it sees none): what a reader checks.
Mode modeOf(const kernels::ZfpStreamParams& params);

// A brick's bits, LSB first in 64-bit words (zfp's bit stream), and how many there are.
struct BrickBits {
  std::vector<std::uint64_t> words;
  std::uint64_t bits = 0;
};
// The most bits zfp writes for a brick of `shape` under `params` (every block at its budget).
std::uint64_t maxStreamBits(const kernels::ZfpStreamParams& params, const BrickShape& shape);
// The bits of a stored brick: its voxels in `type`.
inline std::uint64_t storedBits(ScalarType type, const BrickShape& shape) {
  return std::uint64_t(shape.voxels()) * 8 * scalarBytes(type);
}

// Compresses the brick's voxels (in[x + 16 (y + 16 z)]) block by block, as zfp_compress orders
// them, with no padding after the last block.
BrickBits compressBrick(const kernels::ZfpStreamParams& params, const float* in,
                        const BrickShape& shape);
// The brick's voxels in `type`, x fastest.
BrickBits storeBrick(ScalarType type, const float* in, const BrickShape& shape);
// Appends `b` to `stream` (bytes of 64-bit little-endian words) whose length is `bits` (and adds
// b.bits to it). The stream grows by whole words; reserve it beforehand to keep it in place.
void appendBits(std::vector<std::byte>& stream, std::uint64_t& bits, const BrickBits& b);

// Decodes bits [begin, end) of `stream` (the stream section, `streamBytes` long, a multiple of 8
// bytes holding `end`) into out[x + 16 (y + 16 z)] (other entries left alone). Reads no byte
// outside the brick's words, whatever they hold.
void decodeBrick(const kernels::ZfpStreamParams& params, ScalarType type, bool stored,
                 const std::uint8_t* stream, std::uint64_t begin, std::uint64_t end,
                 const BrickShape& shape, float* out);

// A decoded brick's voxels (out[x + 16 (y + 16 z)]) as the reader gives them: clamped to
// [lo, hi] (NaN to lo), rounded for integer types. The encoder measures the same values.
inline void finishBrick(float* out, const BrickShape& s, float lo, float hi, bool integer) {
  for (int z = 0; z < s.nz; ++z)
    for (int y = 0; y < s.ny; ++y) {
      float* row = out + kBrick * (y + kBrick * z);
      for (int x = 0; x < s.nx; ++x) {
        float v = row[x];
        if (!(v >= lo)) v = lo;
        if (v > hi) v = hi;
        row[x] = integer ? std::nearbyint(v) : v;
      }
    }
}

}  // namespace voxwall::codec::zfp
