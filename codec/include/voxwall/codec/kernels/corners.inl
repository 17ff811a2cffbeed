// The trilinear blend of a cell's corners and the corners' central differences, over a value type
// V (float, or a SIMD vector of the CPU's ray packets). Included on purpose more than once, so no
// include guard: by trilinear.hpp inside namespace voxwall::codec::kernels, and by
// node/src/cpu_view_targets.hpp once per SIMD target inside Highway's target region, so that the
// vector instantiations are compiled for that target (node/include/voxwall/node/kernels/
// raycast_lanes.inl says why). Static members of one struct, so the copies never meet by
// argument-dependent lookup.
struct Corners {
  // The trilinear blend of a cell's eight corner values at fractions (tx, ty, tz) in [0, 1]:
  // corner i sits at (+x if bit 0, +y if bit 1, +z if bit 2). Every view blends through this one
  // function.
  template <class V>
  static VOXWALL_HD_INLINE V blend(const V* c, V tx, V ty, V tz) {
    const V c00 = c[0] + tx * (c[1] - c[0]), c10 = c[2] + tx * (c[3] - c[2]);
    const V c01 = c[4] + tx * (c[5] - c[4]), c11 = c[6] + tx * (c[7] - c[6]);
    const V c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    return c0 + tz * (c1 - c0);
  }

  // The central differences v(i + 1) - v(i - 1) along x, y and z at the eight corners of a voxel
  // cell: d[8 a + i] for axis a and corner i (numbered as in blend). They come from the corners'
  // own values c[8] and 24 more voxels read through at(ox, oy, oz): the voxel at offset (ox, oy,
  // oz) from the cell's lower corner, each offset in {-1, 0, 1, 2}, clamped to the volume the way
  // the view clamps its corners.
  //
  // Blending d[8 a ..] with a sample's fractions gives exactly (up to rounding) the difference of
  // the trilinear samples one voxel before and after it along axis a, wherever the sample lies in
  // [0, dim - 1] (see outsideGrid): each shifted sample blends the corners' neighbours with the
  // same weights. So a view gets the gradient the raycaster used to take six samples (48 voxel
  // reads) for from 24 reads per cell, reused by every sample in the cell.
  template <class V, class At>
  static VOXWALL_HD_INLINE void differences(const V* c, const At& at, V* d) {
    differences(c, at, d, std::make_integer_sequence<int, 24>());
  }
  template <class V, class At, int... K>
  static VOXWALL_HD_INLINE void differences(const V* c, const At& at, V* d,
                                            std::integer_sequence<int, K...>) {
    ((d[K] = difference<K / 8, K % 8>(c, at)), ...);
  }
  // One of them: axis A, corner I, with constant offsets so every read is a fixed address.
  template <int A, int I, class V, class At>
  static VOXWALL_HD_INLINE V difference(const V* c, const At& at) {
    constexpr int bit = 1 << A, x = I & 1, y = (I >> 1) & 1, z = I >> 2;
    if constexpr ((I & bit) != 0)  // the upper corner: two voxels past the lower one, minus it
      return at(A == 0 ? 2 : x, A == 1 ? 2 : y, A == 2 ? 2 : z) - c[I ^ bit];
    else  // the lower corner: the upper one minus the voxel before
      return c[I | bit] - at(A == 0 ? -1 : x, A == 1 ? -1 : y, A == 2 ? -1 : z);
  }
};
