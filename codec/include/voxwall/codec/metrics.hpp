// Quality metrics for codecs.
#pragma once

#include <cstdio>
#include <string>
#include <voxwall/codec/volume.hpp>

namespace voxwall::codec {

// Peak signal-to-noise ratio in dB of `test` against `reference`, with the peak being the
// reference's value range (valueMax - valueMin, or the type's range when that is 0).
// Returns +infinity for identical volumes. Throws std::invalid_argument on a dims mismatch.
double psnr(const Volume& reference, const Volume& test);

// psnr() summed a part at a time, in voxel order (the same sum, so the same value): a streaming
// encoder adds each slab of the reference and of its reconstruction.
class PsnrSum {
 public:
  // The peak from the reference's header (its type, valueMin and valueMax).
  explicit PsnrSum(const Volume& referenceHeader);
  template <class A, class B>
  void add(const A* reference, const B* test, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      const double d = double(reference[i]) - double(test[i]);
      sum_ += d * d;
    }
    count_ += n;
  }
  // n reference values against one test value.
  template <class A>
  void addConstant(const A* reference, double test, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      const double d = double(reference[i]) - test;
      sum_ += d * d;
    }
    count_ += n;
  }
  // A sum of squared differences over n voxels, found elsewhere.
  void addSquares(double squares, std::size_t n) {
    sum_ += squares;
    count_ += n;
  }
  double psnr() const;

 private:
  double peak_ = 1, sum_ = 0;
  std::size_t count_ = 0;
};

// Bits per voxel of a compressed size.
inline double bitsPerVoxel(std::uint64_t bytes, const Volume& v) {
  return v.voxelCount() ? 8.0 * double(bytes) / double(v.voxelCount()) : 0.0;
}

}  // namespace voxwall::codec
