// The baked transfer function as the per-ray code sees it.
#pragma once

#include <glm/vec4.hpp>
#include <type_traits>
#include <vector>
#include <voxwall/codec/kernels/host_device.hpp>

namespace voxwall::node {

namespace kernels {

// `size` RGBA entries over data values [lo, lo + (size - 1) / scale]: straight colour, opacity
// already corrected for the ray step. Linear interpolation between entries, clamped at the ends.
struct TransferLut {
  const glm::vec4* entries = nullptr;  // host or device memory, not owned
  int size = 0;
  float lo = 0.0f;
  float scale = 0.0f;  // entries per data unit

  VOXWALL_HD_INLINE glm::vec4 lookup(float value) const {
    float f = (value - lo) * scale;
    f = f < 0.0f ? 0.0f : (f > float(size - 1) ? float(size - 1) : f);
    const int i = int(f);
    const int j = i + 1 < size ? i + 1 : i;
    const float t = f - float(i);
    const glm::vec4 a = entries[i], b = entries[j];
    return a + t * (b - a);
  }
  // Continuous LUT coordinate of a value, unclamped (for range queries on the host).
  VOXWALL_HD_INLINE float coordinate(float value) const { return (value - lo) * scale; }
};
static_assert(std::is_trivially_copyable_v<TransferLut>);

}  // namespace kernels

// Owns the entries of a TransferLut on the host.
struct HostLut {
  std::vector<glm::vec4> entries;
  float lo = 0.0f, hi = 1.0f;
  kernels::TransferLut view(const glm::vec4* base = nullptr) const {
    kernels::TransferLut lut;
    lut.entries = base ? base : entries.data();
    lut.size = int(entries.size());
    lut.lo = lo;
    lut.scale = hi > lo ? float(entries.size() - 1) / (hi - lo) : 0.0f;
    return lut;
  }
  // Largest opacity any value in [a, b] can get (exact for the linear interpolation above).
  float maxOpacity(float a, float b) const;
};

}  // namespace voxwall::node
