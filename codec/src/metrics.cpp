#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <voxwall/codec/metrics.hpp>

namespace voxwall::codec {

PsnrSum::PsnrSum(const Volume& reference) {
  peak_ = reference.valueMax - reference.valueMin;
  if (peak_ <= 0) {
    switch (reference.type) {
      case ScalarType::UInt8:
        peak_ = 255;
        break;
      case ScalarType::UInt16:
      case ScalarType::Int16:
        peak_ = 65535;
        break;
      case ScalarType::Float32:
        peak_ = 1;
        break;
    }
  }
}

double PsnrSum::psnr() const {
  if (sum_ == 0) return std::numeric_limits<double>::infinity();
  const double mse = sum_ / double(count_);
  return 10.0 * std::log10(peak_ * peak_ / mse);
}

double psnr(const Volume& reference, const Volume& test) {
  if (reference.dims != test.dims) throw std::invalid_argument("psnr: dimensions differ");
  if (reference.type != test.type) {
    PsnrSum sum(reference);
    const std::size_t n = reference.voxelCount();
    for (std::size_t i = 0; i < n; ++i) {
      const double a = reference.valueAt(i), b = test.valueAt(i);
      sum.add(&a, &b, 1);
    }
    return sum.psnr();
  }
  return dispatchScalar(reference.type, [&](auto t) {
    using T = decltype(t);
    PsnrSum sum(reference);
    sum.add(reference.as<T>().data(), test.as<T>().data(), reference.voxelCount());
    return sum.psnr();
  });
}

}  // namespace voxwall::codec
