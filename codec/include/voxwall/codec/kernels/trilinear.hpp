// Trilinear interpolation over any view that answers voxel(x, y, z) with clamp-to-edge.
#pragma once

#include <cmath>
#include <voxwall/core/host_device.hpp>

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

// The trilinear blend of a cell's eight corner values at fractions (tx, ty, tz) in [0, 1]: corner
// i sits at (+x if bit 0, +y if bit 1, +z if bit 2). Every view blends through this one function.
VOXWALL_HD_INLINE float blendCorners(const float* c, float tx, float ty, float tz) {
  const float c00 = c[0] + tx * (c[1] - c[0]), c10 = c[2] + tx * (c[3] - c[2]);
  const float c01 = c[4] + tx * (c[5] - c[4]), c11 = c[6] + tx * (c[7] - c[6]);
  const float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
  return c0 + tz * (c1 - c0);
}

// Clamps a position to [0, hi] per axis (a view's clamp-to-edge: clamping the position gives the
// same sample as clamping the corner indices, and makes the floor a plain truncation).
VOXWALL_HD_INLINE float clampPosition(float p, float hi) {
  return p < 0.0f ? 0.0f : (p > hi ? hi : p);
}

// Sample at continuous index-space position (x, y, z); voxel centres sit on integers.
template <class View>
VOXWALL_HD_INLINE float trilinear(const View& v, float x, float y, float z) {
  const int ix = floorToInt(x), iy = floorToInt(y), iz = floorToInt(z);
  const float fx = float(ix), fy = float(iy), fz = float(iz);
  const float tx = x - fx, ty = y - fy, tz = z - fz;
  float c[8];
  for (int i = 0; i < 8; ++i) c[i] = v.voxel(ix + (i & 1), iy + ((i >> 1) & 1), iz + (i >> 2));
  return blendCorners(c, tx, ty, tz);
}

}  // namespace voxwall::codec::kernels
