// The contract between a codec's view and the raycaster, checked at compile time.
//
// A view is a small, trivially copyable value (it is copied into a CUDA kernel's parameters)
// that answers trilinear samples in index space (voxel centres on integers, clamp-to-edge) from
// the codec's own data, wherever that data lives (host or device memory). Per-ray state lives in
// the view's RayCache, which the raycaster creates once per ray.
#pragma once

#include <concepts>
#include <type_traits>
#include <voxwall/core/host_device.hpp>

namespace voxwall::codec::kernels {

// Every view the raycaster accepts:
//   RayCache                       per-ray state, default-constructible on host and device
//   sample(x, y, z, cache)         the trilinear sample the ray composites; may remember the cell
//   sampleNear(x, y, z, cache)     a gradient neighbour: may share the cache's decoded data but
//                                  must leave what sample() remembers alone
//   sample(x, y, z), voxel(i, j, k) uncached point queries (tests, tools)
//   dimX, dimY, dimZ               the volume's size in voxels
template <class V>
concept VolumeView = std::is_trivially_copyable_v<V> &&
    std::default_initializable<typename V::RayCache> &&
    requires(const V& v, typename V::RayCache& cache, float p, int i) {
  { v.sample(p, p, p, cache) } -> std::same_as<float>;
  { v.sampleNear(p, p, p, cache) } -> std::same_as<float>;
  { v.sample(p, p, p) } -> std::same_as<float>;
  { v.voxel(i, i, i) } -> std::same_as<float>;
  { v.dimX } -> std::convertible_to<int>;
  { v.dimY } -> std::convertible_to<int>;
  { v.dimZ } -> std::convertible_to<int>;
};

// A view with the traversal hook (kTraversal): it samples coarser levels for wide ray footprints,
// can sample the nearest voxel, and reports the box around each sample in which the value is
// constant, so the raycaster can skip it in one step. The raycaster sets `footprint` (voxels)
// and `nearest` before each sample and reads the region after it.
template <class V>
concept TraversalView = VolumeView<V> && V::kTraversal && requires(typename V::RayCache& c) {
  { c.footprint } -> std::convertible_to<float>;
  { c.nearest } -> std::convertible_to<bool>;
  { c.regionValid } -> std::convertible_to<bool>;
  { c.regionLo[0] } -> std::convertible_to<float>;
  { c.regionHi[0] } -> std::convertible_to<float>;
  { c.regionFootprintMax } -> std::convertible_to<float>;
};

// A view with the cell-gradient hook: gradient(x, y, z, cache, g), called right after
// sample(x, y, z, cache) at the same position, writes the central-difference gradient there into
// g[3] (index units, v(i + 1) - v(i - 1) not halved) and returns true, or returns false when it
// has none for this sample (a coarser level, nearest sampling), and the raycaster takes six
// sampleNear() samples instead. Views build it with cornerDifferences (trilinear.hpp) from 24
// voxel reads per cell, kept in the RayCache while the ray stays in the cell.
template <class V>
concept GradientView = VolumeView<V> &&
    requires(const V& v, typename V::RayCache& cache, float p, float* g) {
  { v.gradient(p, p, p, cache, g) } -> std::same_as<bool>;
};

}  // namespace voxwall::codec::kernels
