// The ksvd encoder's codes of the coded bricks' blocks in the file's layout 2 (ksvd_codec.hpp):
// a brick's sparse codes quantized into means, pair counts and pairs, the bytes they take, and
// the sections they are written as. layout.cpp reads them back.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>
#include <voxwall/codec/ksvd_codec.hpp>

namespace voxwall::codec::ksvd {

// The widths of a block's code: a pair's atom index and coefficient, a block's mean.
struct CodeWidths {
  int indexBits = 1, coefBits = 2, meanBits = 1;
  int pairBits() const { return indexBits + coefBits; }
};

// The coded bricks' block codes at one tolerance: per coded brick and block its quantized mean
// and its number of pairs, and the pairs.
struct CodedBricks {
  std::vector<std::vector<std::uint32_t>> means;
  std::vector<std::vector<std::uint8_t>> counts;
  std::vector<std::vector<std::uint32_t>> pairs;  // per coded brick, packPair's words
  std::vector<float> steps;                       // per coded brick, in value units
  std::uint64_t pairCount = 0;

  explicit CodedBricks(std::size_t bricks = 0)
      : means(bricks), counts(bricks), pairs(bricks), steps(bricks) {}
};

// One coded brick's blocks, coded: `codes[i]` is the sparse code (the DC atom first) of block
// `inGrid[i]` of the brick (of `perBrick`), whose m values `y` holds from i x m, relative to the
// brick's minimum and over `scale` (the volume's range); `range` is the brick's max - min. Writes
// brick c of `out`: the pairs' step (their largest coefficient over the largest quantized one,
// in value units), each block's mean in steps of range / (2^meanBits - 1), its pairs whose
// coefficient does not quantize to 0, and their count.
void quantizeBrick(std::span<const SparseCode> codes, const float* y, std::span<const int> inGrid,
                   int m, int perBrick, float scale, double range, const CodeWidths& widths,
                   std::size_t c, CodedBricks& out);

// What every block of `blocks` costs whatever its pairs: its mean and the zero bit ending its
// unary count.
std::uint64_t blockTableBytes(std::uint64_t blocks, int meanBits);
// The bytes of the dc, counts and pairs sections of `codes` (`blocks` blocks).
std::uint64_t codeBytes(const CodedBricks& codes, std::uint64_t blocks, const CodeWidths& widths);

// The sections of `codes`, perBrick blocks a coded brick.
struct CodeSections {
  std::vector<std::byte> counts, pairs, dc;
};
CodeSections codeSections(const CodedBricks& codes, int perBrick, const CodeWidths& widths);

}  // namespace voxwall::codec::ksvd
