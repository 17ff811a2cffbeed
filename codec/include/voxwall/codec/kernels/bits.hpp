// Bit counting on the host and on a device, for the views that index packed bit streams.
#pragma once

#include <cstdint>
#include <voxwall/core/host_device.hpp>

namespace voxwall::codec::kernels {

// The number of one bits of v.
VOXWALL_HD_INLINE int popcount64(std::uint64_t v) {
#if defined(__CUDA_ARCH__)
  return __popcll(v);
#else
  return __builtin_popcountll(v);
#endif
}

// The number of zero bits below v's lowest one bit (64 for v == 0).
VOXWALL_HD_INLINE int trailingZeros64(std::uint64_t v) {
#if defined(__CUDA_ARCH__)
  return __ffsll(static_cast<long long>(v)) - 1 + (v == 0 ? 65 : 0);
#else
  return v == 0 ? 64 : __builtin_ctzll(v);
#endif
}

}  // namespace voxwall::codec::kernels
