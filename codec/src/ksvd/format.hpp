// What the ksvd encoder (codec.cpp) and layout (layout.cpp) share: bounds, index widths and the
// bricking of a volume. The byte layout is documented in ksvd_codec.hpp.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>
#include <glm/vec3.hpp>
#include <voxwall/codec/ksvd_codec.hpp>

namespace voxwall::codec::ksvd {

inline constexpr std::uint32_t kConstant = 0xFFFFFFFFu;
inline constexpr int kMaxAtoms = 1 << 16;

inline int indexBitsFor(int atoms) { return std::max(1, int(std::bit_width(unsigned(atoms - 1)))); }

// A pair is indexBits + coefficient bits wide, at most kMaxPairBits (the 3-byte pairs of files
// from before the width was stored); the pair stream is that many bits per pair, LSB-first,
// padded with zero bits to a whole byte.
inline constexpr int kMinCoefficientBits = 2;
inline constexpr int kMaxPairBits = 24;
inline std::uint64_t pairStreamBytes(std::uint64_t pairs, int pairBits) {
  return (pairs * std::uint64_t(pairBits) + 7) / 8;
}

// The bricking of a volume: blocks of M^3 voxels, bricks of N^3 blocks.
struct Grid {
  int m = 6, n = 5;
  glm::ivec3 dims{}, blocks{}, bricks{};
  Grid(glm::ivec3 d, int side) : m(side), n(ksvd::blocksPerBrick(side)), dims(d) {
    blocks = (dims + m - 1) / m;
    bricks = (blocks + n - 1) / n;
  }
  std::uint64_t brickCount() const {
    return std::uint64_t(bricks.x) * std::uint64_t(bricks.y) * std::uint64_t(bricks.z);
  }
  std::uint64_t blockCount() const {
    return std::uint64_t(blocks.x) * std::uint64_t(blocks.y) * std::uint64_t(blocks.z);
  }
  int blocksPerBrick() const { return n * n * n; }
  glm::ivec3 brickCoords(std::uint64_t b) const {
    return {int(b % std::uint64_t(bricks.x)),
            int(b / std::uint64_t(bricks.x) % std::uint64_t(bricks.y)),
            int(b / (std::uint64_t(bricks.x) * std::uint64_t(bricks.y)))};
  }
  // Block j (x fastest) of a brick, in block coordinates; may lie outside the block grid.
  glm::ivec3 blockOf(glm::ivec3 brick, int j) const {
    return brick * n + glm::ivec3{j % n, (j / n) % n, j / (n * n)};
  }
  bool inGrid(glm::ivec3 b) const { return b.x < blocks.x && b.y < blocks.y && b.z < blocks.z; }
};

}  // namespace voxwall::codec::ksvd
