// Trilinear interpolation over any view that answers voxel(x, y, z) with clamp-to-edge.
#pragma once

#include <cmath>
#include <utility>
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

#include <voxwall/codec/kernels/corners.inl>  // Corners: blend and differences over any value type

// The views' names for them (with floats; the CPU's packets use their own copy of Corners).
template <class V>
VOXWALL_HD_INLINE V blendCorners(const V* c, V tx, V ty, V tz) {
  return Corners::blend(c, tx, ty, tz);
}
template <class V, class At>
VOXWALL_HD_INLINE void cornerDifferences(const V* c, const At& at, V* d) {
  Corners::differences(c, at, d);
}

// Is the position outside [0, hi] on some axis (the volume's outer half voxel, where a view
// clamps it)? There the six shifted samples clamp positions and the corner differences would
// clamp indices, which differ, so the cell-gradient hooks leave those samples to the six samples.
VOXWALL_HD_INLINE bool outsideGrid(float x, float y, float z, float hx, float hy, float hz) {
  return !(x >= 0.0f && y >= 0.0f && z >= 0.0f && x <= hx && y <= hy && z <= hz);
}

// A cell gradient's cache: the cell whose corner differences d holds (ix = -1: none).
struct CellGradient {
  int ix = -1, iy = -1, iz = -1;
  float d[24] = {};
  // Blends the differences at fractions (tx, ty, tz) into g[3].
  VOXWALL_HD_INLINE void blend(float tx, float ty, float tz, float* g) const {
    g[0] = blendCorners(d, tx, ty, tz);
    g[1] = blendCorners(d + 8, tx, ty, tz);
    g[2] = blendCorners(d + 16, tx, ty, tz);
  }
  VOXWALL_HD_INLINE bool holds(int x, int y, int z) const { return x == ix && y == iy && z == iz; }
};

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
