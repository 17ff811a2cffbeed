// The vq encoder's stores for deduplicating bricks and holding the coded codebook (internal to
// codec/src/vq/): what bounds a compress's memory on a volume whose bricks are mostly unique.
#pragma once

#include <xxhash.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::vq {

inline constexpr int kN = kernels::kVqBrickVoxels;  // voxels in a brick

// The bit depth for data of this type and range (8, 12 or 16).
int bitDepth(ScalarType type, double lo, double hi);

// The bits of every value of a plain (uncompressed) codeword, x fastest.
void plainCodeword(const Brick& b, int bits, std::vector<std::uint8_t>& out);

// The bricks of brick row bz (4 slices) into `row` (x fastest, then y), values minus `bias`,
// gathered on `threads` threads; `window` is scratch of 4 slices.
void gatherRow(const VolumeSource& volume, int bz, int bias, int threads,
               std::vector<std::byte>& window, std::vector<Brick>& row);

// An open-addressing set of indices 0 .. n-1 into a store that hashes and compares its items; at
// most half full, 4 bytes a slot.
class OpenIndex {
 public:
  // The index of the item with hash `hash` for which equal(index) holds; else `next` is added
  // (`added`). hashOf(index) rehashes the store's items when the table grows.
  template <class Equal, class HashOf>
  std::uint32_t findOrAdd(std::uint64_t hash, std::size_t next, const Equal& equal,
                          const HashOf& hashOf, bool& added) {
    if (2 * (next + 1) > table_.size()) grow(next, hashOf);
    const std::size_t mask = table_.size() - 1;
    for (std::size_t at = hash & mask;; at = (at + 1) & mask) {
      const std::uint32_t entry = table_[at];
      if (entry == 0) {
        if (next >= std::numeric_limits<std::uint32_t>::max() - 1)
          throw std::length_error("vq codec: more than 2^32 - 2 distinct bricks");
        table_[at] = std::uint32_t(next + 1);
        added = true;
        return std::uint32_t(next);
      }
      if (equal(entry - 1)) {
        added = false;
        return entry - 1;
      }
    }
  }
  void clear() { std::vector<std::uint32_t>().swap(table_); }

 private:
  template <class HashOf>
  void grow(std::size_t count, const HashOf& hashOf) {
    std::vector<std::uint32_t> table(std::max<std::size_t>(1024, table_.size() * 2), 0);
    const std::size_t mask = table.size() - 1;
    for (std::size_t i = 0; i < count; ++i) {
      std::size_t at = hashOf(i) & mask;
      while (table[at] != 0) at = (at + 1) & mask;
      table[at] = std::uint32_t(i + 1);
    }
    table_.swap(table);
  }
  std::vector<std::uint32_t> table_;  // 0: empty, else index + 1
};

// Bytes appended in chunks that never move (no copy of the whole as it grows), read as one
// array.
class ChunkedBytes {
 public:
  std::uint64_t size() const { return size_; }
  void append(const std::uint8_t* p, std::size_t n);
  // Bytes [at, at + n) into out.
  void read(std::uint64_t at, std::size_t n, std::uint8_t* out) const;
  void copyTo(std::byte* out) const;  // all of them
  void clear() {
    chunks_.clear();
    size_ = 0;
  }

 private:
  static constexpr std::size_t kChunk = std::size_t(1) << 20;
  std::vector<std::unique_ptr<std::uint8_t[]>> chunks_;
  std::uint64_t size_ = 0;
};

// The distinct bricks seen so far, each once, in the order first seen: a byte a voxel where the
// data has at most 8 bits (64 bytes a brick instead of 128), in chunks that never move.
class UniqueBricks {
 public:
  explicit UniqueBricks(int bits) : width_(bits > 8 ? 2 : 1) {}
  std::size_t size() const { return count_; }
  // The index of brick b, added at the end where it is new (`added`).
  std::uint32_t insert(const Brick& b, bool& added);
  Brick operator[](std::size_t i) const;
  // Done adding: the index goes.
  void seal() { index_.clear(); }
  std::vector<Brick> all() const;
  void clear() {
    seal();
    bytes_.clear();
    count_ = 0;
  }

 private:
  std::size_t width_;
  ChunkedBytes bytes_;
  OpenIndex index_;
  std::size_t count_ = 0;
};

// A coded codebook and the offset volume's entries.
struct CodedBook {
  ChunkedBytes bytes;                          // the codewords, in order
  std::vector<std::uint64_t> address;          // each codeword's first byte in `bytes`
  std::vector<std::uint32_t> brickToCodeword;  // per brick, x fastest
};

// The lossless codebook straight from the input: each row of bricks coded in parallel (RBUC when
// `compressed`, else plain), then deduplicated on the codes in brick order. A code stands for
// one brick and equal bricks give equal codes, so the codebook is the one deduplicating the
// bricks first gives, byte for byte, but no brick is held beyond its row: what the encoder keeps
// is the codebook it writes. Fills stats' unique bricks, escapes and transform counts.
CodedBook losslessBook(const VolumeSource& volume, int bits, int bias, bool compressed, int threads,
                       Progress& progress, EncodeStats& stats);

}  // namespace voxwall::codec::vq
