// Trilinear interpolation over any view that answers voxel(x, y, z) with clamp-to-edge.
#pragma once

#include <cmath>
#include <voxwall/codec/kernels/host_device.hpp>

namespace voxwall::codec::kernels {

VOXWALL_HD_INLINE int clampIndex(int i, int n) { return i < 0 ? 0 : (i >= n ? n - 1 : i); }

// floor() for |x| < 2^31. floorf is a library routine on baseline x86-64 (no SSE4.1), about 45
// instructions; this is a truncation and a compare.
VOXWALL_HD_INLINE int floorToInt(float x) {
  const int i = int(x);
  return i - int(x < float(i));
}

// ceil() for |x| < 2^31, for the same reason.
VOXWALL_HD_INLINE int ceilToInt(float x) {
  const int i = int(x);
  return i + int(x > float(i));
}

// Sample at continuous index-space position (x, y, z); voxel centres sit on integers.
template <class View>
VOXWALL_HD_INLINE float trilinear(const View& v, float x, float y, float z) {
  const int ix = floorToInt(x), iy = floorToInt(y), iz = floorToInt(z);
  const float fx = float(ix), fy = float(iy), fz = float(iz);
  const float tx = x - fx, ty = y - fy, tz = z - fz;
  const float c000 = v.voxel(ix, iy, iz), c100 = v.voxel(ix + 1, iy, iz);
  const float c010 = v.voxel(ix, iy + 1, iz), c110 = v.voxel(ix + 1, iy + 1, iz);
  const float c001 = v.voxel(ix, iy, iz + 1), c101 = v.voxel(ix + 1, iy, iz + 1);
  const float c011 = v.voxel(ix, iy + 1, iz + 1), c111 = v.voxel(ix + 1, iy + 1, iz + 1);
  const float c00 = c000 + tx * (c100 - c000), c10 = c010 + tx * (c110 - c010);
  const float c01 = c001 + tx * (c101 - c001), c11 = c011 + tx * (c111 - c011);
  const float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
  return c0 + tz * (c1 - c0);
}

}  // namespace voxwall::codec::kernels
