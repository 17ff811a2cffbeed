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

// The trilinear blend of a cell's eight corner values at fractions (tx, ty, tz) in [0, 1]: corner
// i sits at (+x if bit 0, +y if bit 1, +z if bit 2). Every view blends through this one function
// (V: float, or a SIMD vector of the CPU's ray packets).
template <class V>
VOXWALL_HD_INLINE V blendCorners(const V* c, V tx, V ty, V tz) {
  const V c00 = c[0] + tx * (c[1] - c[0]), c10 = c[2] + tx * (c[3] - c[2]);
  const V c01 = c[4] + tx * (c[5] - c[4]), c11 = c[6] + tx * (c[7] - c[6]);
  const V c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
  return c0 + tz * (c1 - c0);
}

// The central differences v(i + 1) - v(i - 1) along x, y and z at the eight corners of a voxel
// cell: d[8 a + i] for axis a and corner i (numbered as in blendCorners). They come from the
// corners' own values c[8] and 24 more voxels read through at(ox, oy, oz): the voxel at offset
// (ox, oy, oz) from the cell's lower corner, each offset in {-1, 0, 1, 2}, clamped to the volume
// the way the view clamps its corners.
//
// Blending d[8 a ..] with a sample's fractions gives exactly (up to rounding) the difference of
// the trilinear samples one voxel before and after it along axis a, wherever the sample lies in
// [0, dim - 1] (see outsideGrid): each shifted sample blends the corners' neighbours with the
// same weights. So a
// view gets the gradient the raycaster used to take six samples (48 voxel reads) for from 24
// reads per cell, reused by every sample in the cell.
// One of them: axis A, corner I, with constant offsets so every read is a fixed address.
template <int A, int I, class V, class At>
VOXWALL_HD_INLINE V cornerDifference(const V* c, const At& at) {
  constexpr int bit = 1 << A, x = I & 1, y = (I >> 1) & 1, z = I >> 2;
  if constexpr ((I & bit) != 0)  // the upper corner: two voxels past the lower one, minus it
    return at(A == 0 ? 2 : x, A == 1 ? 2 : y, A == 2 ? 2 : z) - c[I ^ bit];
  else  // the lower corner: the upper one minus the voxel before
    return c[I | bit] - at(A == 0 ? -1 : x, A == 1 ? -1 : y, A == 2 ? -1 : z);
}
template <class V, class At, int... K>
VOXWALL_HD_INLINE void cornerDifferences(const V* c, const At& at, V* d,
                                         std::integer_sequence<int, K...>) {
  ((d[K] = cornerDifference<K / 8, K % 8>(c, at)), ...);
}
template <class V, class At>
VOXWALL_HD_INLINE void cornerDifferences(const V* c, const At& at, V* d) {
  cornerDifferences(c, at, d, std::make_integer_sequence<int, 24>());
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
