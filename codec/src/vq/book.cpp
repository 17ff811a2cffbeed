// The vq encoder's brick and codebook stores, and the lossless codebook coded row by row.
#include "book.hpp"

#include <voxwall/core/parallel.hpp>

namespace voxwall::codec::vq {

namespace {

// Brick (bx, by) of a row from `window`, the row's 4 slices (x fastest), minus `bias`.
template <class T>
void gatherBrick(glm::ivec3 dims, const T* window, int bias, int bx, int by, Brick& out) {
  int i = 0;
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y) {
      const int vy = std::min(by * 4 + y, dims.y - 1);
      const T* line =
          window + (std::size_t(z) * std::size_t(dims.y) + std::size_t(vy)) * std::size_t(dims.x);
      for (int x = 0; x < 4; ++x)
        out[i++] = std::uint16_t(int(line[std::min(bx * 4 + x, dims.x - 1)]) - bias);
    }
}

}  // namespace

void gatherRow(const VolumeSource& volume, int bz, int bias, int threads,
               std::vector<std::byte>& window, std::vector<Brick>& row) {
  const glm::ivec3 bricks = (volume.dims + 3) / 4;
  window.resize(4 * volume.sliceBytes());
  row.resize(std::size_t(bricks.x) * std::size_t(bricks.y));
  volume.readSlices(bz * 4, 4, window);
  dispatchScalar(volume.type, [&](auto t) {
    using T = decltype(t);
    if constexpr (std::is_integral_v<T>) {
      const T* src = reinterpret_cast<const T*>(window.data());
      parallelFor(std::size_t(bricks.y), threads, [&](std::size_t by) {
        for (int bx = 0; bx < bricks.x; ++bx)
          gatherBrick<T>(volume.dims, src, bias, bx, int(by),
                         row[by * std::size_t(bricks.x) + std::size_t(bx)]);
      });
    }
  });
}

void ChunkedBytes::append(const std::uint8_t* p, std::size_t n) {
  while (n > 0) {
    const std::size_t at = std::size_t(size_ % kChunk);
    if (at == 0) chunks_.push_back(std::make_unique<std::uint8_t[]>(kChunk));
    const std::size_t take = std::min(n, kChunk - at);
    std::memcpy(chunks_.back().get() + at, p, take);
    p += take, n -= take, size_ += take;
  }
}

void ChunkedBytes::read(std::uint64_t at, std::size_t n, std::uint8_t* out) const {
  while (n > 0) {
    const std::size_t in = std::size_t(at % kChunk);
    const std::size_t take = std::min(n, kChunk - in);
    std::memcpy(out, chunks_[std::size_t(at / kChunk)].get() + in, take);
    out += take, at += take, n -= take;
  }
}

void ChunkedBytes::copyTo(std::byte* out) const {
  for (std::size_t c = 0; c < chunks_.size(); ++c) {
    const std::size_t n = std::size_t(std::min<std::uint64_t>(kChunk, size_ - c * kChunk));
    std::memcpy(out + c * kChunk, chunks_[c].get(), n);
  }
}

std::uint32_t UniqueBricks::insert(const Brick& b, bool& added) {
  std::uint8_t packed[kN * 2];
  for (int d = 0; d < kN; ++d)
    if (width_ == 1) {
      packed[d] = std::uint8_t(b[d]);
    } else {
      packed[2 * d] = std::uint8_t(b[d]), packed[2 * d + 1] = std::uint8_t(b[d] >> 8);
    }
  const std::size_t bytes = std::size_t(kN) * width_;
  std::uint8_t other[kN * 2];
  auto equal = [&](std::uint32_t i) {
    bytes_.read(std::uint64_t(i) * bytes, bytes, other);
    return std::memcmp(other, packed, bytes) == 0;
  };
  auto hashOf = [&](std::size_t i) {
    bytes_.read(std::uint64_t(i) * bytes, bytes, other);
    return XXH3_64bits(other, bytes);
  };
  const std::uint32_t i =
      index_.findOrAdd(XXH3_64bits(packed, bytes), count_, equal, hashOf, added);
  if (added) bytes_.append(packed, bytes), ++count_;
  return i;
}

Brick UniqueBricks::operator[](std::size_t i) const {
  std::uint8_t p[kN * 2];
  bytes_.read(std::uint64_t(i) * kN * width_, std::size_t(kN) * width_, p);
  Brick b;
  for (int d = 0; d < kN; ++d)
    b[d] = width_ == 1 ? p[d] : std::uint16_t(p[2 * d] | (p[2 * d + 1] << 8));
  return b;
}

std::vector<Brick> UniqueBricks::all() const {
  std::vector<Brick> out(count_);
  for (std::size_t i = 0; i < count_; ++i) out[i] = (*this)[i];
  return out;
}

CodedBook losslessBook(const VolumeSource& volume, int bits, int bias, bool compressed, int threads,
                       Progress& progress, EncodeStats& stats) {
  const glm::ivec3 bricks = (volume.dims + 3) / 4;
  const std::size_t rowBricks = std::size_t(bricks.x) * std::size_t(bricks.y);
  CodedBook book;
  book.brickToCodeword.resize(rowBricks * std::size_t(bricks.z));
  std::vector<std::uint8_t> length;  // per codeword: a codeword is at most 133 bytes
  OpenIndex index;
  std::vector<std::byte> window;
  std::vector<Brick> row;
  // Per brick row y: its bricks' codes, their lengths and transformations.
  std::vector<std::vector<std::uint8_t>> coded(std::size_t(bricks.y));
  std::vector<std::uint8_t> rowLength(rowBricks);
  std::vector<std::int16_t> used(rowBricks, -1);
  progress.begin("bricking and coding", rowBricks * std::size_t(bricks.z));
  for (int bz = 0; bz < bricks.z; ++bz) {
    gatherRow(volume, bz, bias, threads, window, row);
    parallelFor(std::size_t(bricks.y), threads, [&](std::size_t by) {
      coded[by].clear();
      for (std::size_t j = by * std::size_t(bricks.x); j < (by + 1) * std::size_t(bricks.x); ++j) {
        const std::size_t before = coded[by].size();
        if (compressed)
          used[j] = std::int16_t(encodeCodeword(row[j], bits, coded[by]));
        else
          plainCodeword(row[j], bits, coded[by]);
        rowLength[j] = std::uint8_t(coded[by].size() - before);
      }
    });
    // In brick order, so the codebook is the same whatever the threads.
    std::uint8_t other[256];
    for (std::size_t by = 0, j = 0; by < std::size_t(bricks.y); ++by) {
      const std::uint8_t* p = coded[by].data();
      for (int bx = 0; bx < bricks.x; ++bx, ++j) {
        const std::size_t n = rowLength[j];
        auto equal = [&](std::uint32_t i) {
          if (length[i] != n) return false;
          book.bytes.read(book.address[i], n, other);
          return std::memcmp(other, p, n) == 0;
        };
        auto hashOf = [&](std::size_t i) {
          book.bytes.read(book.address[i], length[i], other);
          return XXH3_64bits(other, length[i]);
        };
        bool added = false;
        const std::uint32_t c =
            index.findOrAdd(XXH3_64bits(p, n), length.size(), equal, hashOf, added);
        if (added) {
          book.address.push_back(book.bytes.size());
          length.push_back(std::uint8_t(n));
          book.bytes.append(p, n);
          if (used[j] == kernels::kVqEscape)
            ++stats.escapes;
          else if (used[j] >= 0)
            ++stats.transformUse[used[j]];
        }
        book.brickToCodeword[std::size_t(bz) * rowBricks + j] = c;
        p += n;
      }
    }
    progress.advance(rowBricks);
  }
  progress.end();
  stats.uniqueBricks = length.size();
  return book;
}

}  // namespace voxwall::codec::vq
