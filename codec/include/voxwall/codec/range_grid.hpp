// Coarse value ranges of a volume, for empty-space skipping.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <span>
#include <type_traits>
#include <vector>
#include <voxwall/codec/volume.hpp>

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
  std::size_t bytes() const { return bytes_.size(); }

  // Cell `c`'s range is [lo, hi] (rounded outwards to the type). Cells may be set from several
  // threads at once, each cell by one.
  void set(std::size_t c, float lo, float hi) {
    dispatchScalar(type_, [&]<class T>(T) { put<T>(c, {low<T>(lo), high<T>(hi)}); });
  }
  // Cell `c`'s range grows to hold `value`.
  void widen(std::size_t c, float value) {
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
    return dispatchScalar(type_, [&]<class T>(T) { return float(get<T>(c).lo); });
  }
  float hi(std::size_t c) const {
    return dispatchScalar(type_, [&]<class T>(T) { return float(get<T>(c).hi); });
  }
  // f(cell, lo, hi) for every cell, x fastest.
  template <class F>
  void forEach(F&& f) const {
    dispatchScalar(type_, [&]<class T>(T) {
      const std::size_t n = cellCount();
      for (std::size_t c = 0; c < n; ++c) {
        const Pair<T> p = get<T>(c);
        f(c, float(p.lo), float(p.hi));
      }
    });
  }
  bool operator==(const RangeGrid& o) const {
    return cellVoxels_ == o.cellVoxels_ && cells_ == o.cells_ && type_ == o.type_ &&
           bytes_ == o.bytes_;
  }

 private:
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
  template <class T>
  static T low(float v) {
    if constexpr (std::is_floating_point_v<T>) {
      return v;
    } else {
      constexpr float kMin = float(std::numeric_limits<T>::lowest());
      constexpr float kMax = float(std::numeric_limits<T>::max());
      return T(std::isnan(v) ? kMin : std::clamp(std::floor(v), kMin, kMax));
    }
  }
  template <class T>
  static T high(float v) {
    if constexpr (std::is_floating_point_v<T>) {
      return v;
    } else {
      constexpr float kMin = float(std::numeric_limits<T>::lowest());
      constexpr float kMax = float(std::numeric_limits<T>::max());
      return T(std::isnan(v) ? kMax : std::clamp(std::ceil(v), kMin, kMax));
    }
  }

  int cellVoxels_ = 8;
  glm::ivec3 cells_{0, 0, 0};
  ScalarType type_ = ScalarType::Float32;
  std::vector<std::byte> bytes_;  // per cell: lo, hi in type_
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
