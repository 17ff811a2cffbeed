// Coarse value ranges of a volume, for empty-space skipping.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <span>
#include <stdexcept>
#include <type_traits>
#include <vector>
#include <voxwall/codec/volume.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {

class VolumeSource;  // volume_source.hpp

// Min/max of the voxel values in each cell of cellVoxels^3 voxels, *dilated by one voxel* on
// every side (clamped at the border): every trilinear sample whose lower corner voxel lies in a
// cell interpolates only voxels the cell's range covers. Cells are x fastest.
//
// Held in the volume's own scalar type, two values a cell (uint8: 2 bytes a 4^3 cell, 1/32 of the
// voxels; as two floats it was 8 bytes, 119 MiB at 0.95 Gvox while a volume opened, before the
// renderer packed it). Integer types round outwards (floor the low end, ceil the high end, clamped
// to the type, whose values are all an integer codec's decoder gives); a NaN end widens to the
// type's whole range (float: stays NaN). A wider range only skips less, never a visible sample.
class RangeGrid {
 public:
  RangeGrid() = default;
  // Every cell empty (its low end above its high end) until set() or widen() gives it values.
  RangeGrid(int cellVoxels, glm::ivec3 cells, ScalarType type);

  int cellVoxels() const { return cellVoxels_; }
  glm::ivec3 cells() const { return cells_; }
  ScalarType type() const { return type_; }
  std::size_t cellCount() const {
    return std::size_t(cells_.x) * std::size_t(cells_.y) * std::size_t(cells_.z);
  }
  std::size_t cellIndex(int cx, int cy, int cz) const {
    return (std::size_t(cz) * std::size_t(cells_.y) + std::size_t(cy)) * std::size_t(cells_.x) +
           std::size_t(cx);
  }
  // Bytes the ranges take in memory (compressed, once packed).
  std::size_t bytes() const { return packed_ ? packedBytes_.size() : bytes_.size(); }

  // Compresses the ranges (zlib, in chunks of kChunkCells cells): what a renderer keeps for the
  // volume's lifetime but reads only when a transfer function changes (forEach). On the 0.95 Gvox
  // MRI with noise, 28.4 MiB of uint8 ranges took 9.8-11.6 MiB (by codec). Once packed, set(),
  // widen(), lo() and hi() throw std::logic_error.
  void pack();
  bool packed() const { return packed_; }
  static constexpr std::size_t kChunkCells = std::size_t(1) << 16;  // a multiple of 32

  // Cell `c`'s range is [lo, hi] (rounded outwards to the type). Cells may be set from several
  // threads at once, each cell by one.
  void set(std::size_t c, float lo, float hi) {
    refusePacked();
    dispatchScalar(type_, [&]<class T>(T) { put<T>(c, {low<T>(lo), high<T>(hi)}); });
  }
  // Cell `c`'s range grows to hold `value`.
  void widen(std::size_t c, float value) {
    refusePacked();
    dispatchScalar(type_, [&]<class T>(T) {
      const Pair<T> p = get<T>(c);
      if constexpr (std::is_floating_point_v<T>) {  // a NaN end stays: the whole range
        if (std::isnan(value) || std::isnan(p.lo) || std::isnan(p.hi))
          return put<T>(c,
                        {std::numeric_limits<T>::quiet_NaN(), std::numeric_limits<T>::quiet_NaN()});
      }
      put<T>(c, {std::min(p.lo, low<T>(value)), std::max(p.hi, high<T>(value))});
    });
  }
  float lo(std::size_t c) const {
    refusePacked();
    return dispatchScalar(type_, [&]<class T>(T) { return float(get<T>(c).lo); });
  }
  float hi(std::size_t c) const {
    refusePacked();
    return dispatchScalar(type_, [&]<class T>(T) { return float(get<T>(c).hi); });
  }
  // f(cell, lo, hi) for every cell, x fastest.
  template <class F>
  void forEach(F&& f) const {
    forEachParallel(1, f);
  }
  // The same on `threads` threads (0: every usable core), a chunk of kChunkCells consecutive
  // cells per task: f is called for one chunk's cells by one thread, for different chunks at once.
  template <class F>
  void forEachParallel(int threads, F&& f) const {
    forEachChunk(threads, [&](std::size_t first, std::size_t n, const std::byte* pairs) {
      visit(first, n, pairs, f);
    });
  }
  bool operator==(const RangeGrid& o) const {
    return cellVoxels_ == o.cellVoxels_ && cells_ == o.cells_ && type_ == o.type_ &&
           packed_ == o.packed_ && bytes_ == o.bytes_ && packedBytes_ == o.packedBytes_;
  }

 private:
  void refusePacked() const {
    if (packed_) throw std::logic_error("a packed range grid is read with forEach only");
  }
  std::size_t pairBytes() const { return 2 * scalarBytes(type_); }
  // chunk(first, n, pairs) for every chunk of cells on `threads` threads (pairs: n cells' lo, hi
  // in type_), inflated into a buffer of the task's own when packed.
  template <class F>
  void forEachChunk(int threads, F&& chunk) const {
    const std::size_t n = cellCount(), chunks = (n + kChunkCells - 1) / kChunkCells;
    parallelFor(chunks, threads, [&](std::size_t k) {
      const std::size_t first = k * kChunkCells, count = std::min(kChunkCells, n - first);
      if (!packed_) return chunk(first, count, bytes_.data() + first * pairBytes());
      std::vector<std::byte> pairs(count * pairBytes());
      inflateChunk(k, pairs);
      chunk(first, count, pairs.data());
    });
  }
  void inflateChunk(std::size_t k, std::span<std::byte> out) const;
  template <class F>
  void visit(std::size_t first, std::size_t n, const std::byte* pairs, F& f) const {
    dispatchScalar(type_, [&]<class T>(T) {
      for (std::size_t i = 0; i < n; ++i) {
        Pair<T> p;
        std::memcpy(&p, pairs + i * sizeof p, sizeof p);
        f(first + i, float(p.lo), float(p.hi));
      }
    });
  }

  template <class T>
  struct Pair {
    T lo, hi;
  };
  template <class T>
  Pair<T> get(std::size_t c) const {
    Pair<T> p;
    std::memcpy(&p, bytes_.data() + c * sizeof p, sizeof p);
    return p;
  }
  template <class T>
  void put(std::size_t c, Pair<T> p) {
    std::memcpy(bytes_.data() + c * sizeof p, &p, sizeof p);
  }
  // v rounded outwards to T: down for a range's low end, up for its high end (NaN: the type's
  // whole range; float keeps v).
  template <class T, bool kHigh>
  static T outwards(float v) {
    if constexpr (std::is_floating_point_v<T>) {
      return v;
    } else {
      constexpr float kMin = float(std::numeric_limits<T>::lowest());
      constexpr float kMax = float(std::numeric_limits<T>::max());
      if (std::isnan(v)) return T(kHigh ? kMax : kMin);
      return T(std::clamp(kHigh ? std::ceil(v) : std::floor(v), kMin, kMax));
    }
  }
  template <class T>
  static T low(float v) {
    return outwards<T, false>(v);
  }
  template <class T>
  static T high(float v) {
    return outwards<T, true>(v);
  }

  int cellVoxels_ = 8;
  glm::ivec3 cells_{0, 0, 0};
  ScalarType type_ = ScalarType::Float32;
  std::vector<std::byte> bytes_;  // per cell: lo, hi in type_ (empty once packed)
  bool packed_ = false;
  std::vector<std::byte> packedBytes_;       // the chunks, zlib streams one after another
  std::vector<std::uint64_t> chunkOffsets_;  // chunk k: [offsets[k], offsets[k + 1])
};

// Computes the grid from a dense volume (multi-threaded).
RangeGrid computeRangeGrid(const Volume& volume, int cellVoxels);
// The same from a volume read a layer of cells (and the slice either side) at a time.
RangeGrid computeRangeGrid(const VolumeSource& source, int cellVoxels);
// The grid a layer of cells at a time, without holding it: layerDone(cz, lo, hi) with the cells
// of layer cz, x fastest (an encoder that stores the ranges in its own form).
void forEachRangeLayer(
    const VolumeSource& source, int cellVoxels,
    const std::function<void(int, std::span<const float>, std::span<const float>)>& layerDone);

}  // namespace voxwall::codec
