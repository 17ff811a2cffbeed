#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <voxwall/codec/metrics.hpp>

namespace voxwall::codec {

double psnr(const Volume& reference, const Volume& test) {
  if (reference.dims != test.dims) throw std::invalid_argument("psnr: dimensions differ");
  double peak = reference.valueMax - reference.valueMin;
  if (peak <= 0) {
    switch (reference.type) {
      case ScalarType::UInt8:
        peak = 255;
        break;
      case ScalarType::UInt16:
      case ScalarType::Int16:
        peak = 65535;
        break;
      case ScalarType::Float32:
        peak = 1;
        break;
    }
  }
  double sum = 0;
  const std::size_t n = reference.voxelCount();
  for (std::size_t i = 0; i < n; ++i) {
    const double d = reference.valueAt(i) - test.valueAt(i);
    sum += d * d;
  }
  if (sum == 0) return std::numeric_limits<double>::infinity();
  const double mse = sum / double(n);
  return 10.0 * std::log10(peak * peak / mse);
}

std::string humanBytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024 && u < 4) bytes /= 1024, ++u;
  char buf[32];
  std::snprintf(buf, sizeof buf, u ? "%.1f %s" : "%.0f %s", bytes, units[u]);
  return buf;
}

}  // namespace voxwall::codec
