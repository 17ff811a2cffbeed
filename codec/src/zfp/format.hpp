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
// a u32 per brick. Reads host memory; the Layout has checked it.
struct Index {
  const std::uint8_t* at = nullptr;
  std::uint64_t rows = 0, bricksX = 0;
  std::uint64_t rowBase(std::uint64_t r) const {
    std::uint64_t v;
    std::memcpy(&v, at + 8 * r, 8);
    return v;
  }
  std::uint32_t entry(std::uint64_t brick) const {
    std::uint32_t v;
    std::memcpy(&v, at + 8 * (rows + 1) + 4 * brick, 4);
    return v;
  }
  bool stored(std::uint64_t brick) const { return entry(brick) & kStoredFlag; }
  std::uint64_t begin(std::uint64_t brick) const {
    return rowBase(brick / bricksX) + (entry(brick) & ~kStoredFlag);
  }
  std::uint64_t end(std::uint64_t brick) const {
    return (brick + 1) % bricksX ? begin(brick + 1) : rowBase(brick / bricksX + 1);
  }
  static std::uint64_t bytes(std::uint64_t rows, std::uint64_t bricks) {
    return 8 * (rows + 1) + 4 * bricks;
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
