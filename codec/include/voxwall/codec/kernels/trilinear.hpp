// Trilinear interpolation over any view that answers voxel(x, y, z) with clamp-to-edge.
#pragma once

#include <cmath>
#include <voxwall/codec/kernels/host_device.hpp>

namespace voxwall::codec::kernels {

// Sample at continuous index-space position (x, y, z); voxel centres sit on integers.
template <class View>
VOXWALL_HD_INLINE float trilinear(const View& v, float x, float y, float z) {
  const float fx = floorf(x), fy = floorf(y), fz = floorf(z);
  const int ix = int(fx), iy = int(fy), iz = int(fz);
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

VOXWALL_HD_INLINE int clampIndex(int i, int n) { return i < 0 ? 0 : (i >= n ? n - 1 : i); }

}  // namespace voxwall::codec::kernels
