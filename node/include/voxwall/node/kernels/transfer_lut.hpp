// The baked transfer function as the per-ray code sees it.
#pragma once

#include <glm/vec4.hpp>
#include <type_traits>
#include <vector>
#include <voxwall/core/host_device.hpp>

namespace voxwall::node {

namespace kernels {

// `size` RGBA entries over data values [lo, lo + (size - 1) / scale]: straight colour, opacity
// already corrected for the ray step. Linear interpolation between entries, clamped at the ends.
//
// Pre-integrated (integral set; Engel, Kraus and Ertl 2001, "High-quality pre-integrated volume
// rendering using hardware-accelerated pixel shading"): an entry's fourth channel is instead the
// optical depth of one ray step at that value (-ln(1 - opacity) x step in voxels), and integral[i]
// holds the integrals from entry 0 to entry i, over the table coordinate, of colour x depth (rgb)
// and of depth (a), exact for the linear interpolation between entries. A ray segment whose value
// runs linearly from sf to sb then has the mean depth (G(sb) - G(sf)) / (sb - sf) and the
// depth-weighted mean colour (K(sb) - K(sf)) / (G(sb) - G(sf)): one lookup of each end instead of
// samples finer than the transfer function.
struct TransferLut {
  const glm::vec4* entries = nullptr;   // host or device memory, not owned
  const glm::vec4* integral = nullptr;  // likewise; null: not pre-integrated
  int size = 0;
  float lo = 0.0f;
  float scale = 0.0f;  // entries per data unit
  float last = 0.0f;   // size - 1, as a float
  // entries[size] repeats entries[size - 1], so the upper neighbour needs no clamp.

  VOXWALL_HD_INLINE glm::vec4 lookup(float value) const {
    float f = (value - lo) * scale;
    f = f < 0.0f ? 0.0f : (f > last ? last : f);
    const int i = int(f);
    const float t = f - float(i);
    const glm::vec4 a = entries[i], b = entries[i + 1];
    return a + t * (b - a);
  }
  // Continuous LUT coordinate of a value, unclamped (for range queries on the host).
  VOXWALL_HD_INLINE float coordinate(float value) const { return (value - lo) * scale; }
};
static_assert(std::is_trivially_copyable_v<TransferLut>);

}  // namespace kernels

// Owns the entries of a TransferLut on the host: the table plus one guard entry repeating the
// last (see TransferLut::lookup).
struct HostLut {
  std::vector<glm::vec4> entries;  // size() = table size + 1
  // Pre-integrated tables (kernels::TransferLut::integral), the same size as entries; empty when
  // the table is not pre-integrated.
  std::vector<glm::vec4> integral;
  float lo = 0.0f, hi = 1.0f;
  // The kernel's view of the table: on the host, or on a device copy at `base` that holds
  // entries followed by integral (see packed()).
  kernels::TransferLut view(const glm::vec4* base = nullptr) const {
    kernels::TransferLut lut;
    lut.entries = base ? base : entries.data();
    if (!integral.empty()) lut.integral = base ? base + entries.size() : integral.data();
    lut.size = int(entries.size()) - 1;
    lut.lo = lo;
    lut.scale = hi > lo ? float(lut.size - 1) / (hi - lo) : 0.0f;
    lut.last = float(lut.size - 1);
    return lut;
  }
  // entries followed by integral, as a device copy holds them.
  std::vector<glm::vec4> packed() const {
    std::vector<glm::vec4> all(entries);
    all.insert(all.end(), integral.begin(), integral.end());
    return all;
  }
  // Largest opacity any value in [a, b] can get (exact for the linear interpolation above; for a
  // pre-integrated table the largest depth, zero exactly where the opacity is).
  // O(1) once buildRangeMax() has run (bake() runs it), a scan of the table otherwise.
  float maxOpacity(float a, float b) const;
  // Builds the sparse table behind maxOpacity(): level l holds the max over 2^l entries.
  void buildRangeMax();

 private:
  std::vector<std::vector<float>> rangeMax_;
};

}  // namespace voxwall::node
