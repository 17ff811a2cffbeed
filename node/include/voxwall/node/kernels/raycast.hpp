// The per-ray code shared by the CPU and CUDA backends: ray generation for a pixel of the virtual
// screen, ray/box entry, fixed-step sampling, transfer-function lookup, Blinn-Phong shading,
// front-to-back compositing with early termination, and empty-space skipping.
//
// Spaces: world space is voxel index x spacing with the volume centred at the origin; the ray is
// marched in *index space* (voxel centres on integers, the volume box [-0.5, dims - 0.5]) with
// the ray parameter t measured in world units, so a step of `stepWorld` is the same physical
// length along every ray whatever the spacing.
#pragma once

#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <type_traits>
#include <voxwall/codec/kernels/trilinear.hpp>
#include <voxwall/codec/kernels/view_concept.hpp>
#include <voxwall/core/host_device.hpp>
#include <voxwall/node/kernels/transfer_lut.hpp>

namespace voxwall::node::kernels {

// Empty-space skipping in two levels, both x fastest, set = the transfer function is zero over
// the cell's value range (grown by one voxel): coarse cells of 2^cellShift voxels (a byte each),
// which rays jump over, and fine cells of 2^fineShift voxels (a bit each: bit c % 32 of word
// c / 32, an eighth of a byte grid's memory on every rank), checked per sample inside non-empty
// coarse cells so a transparent sample costs a word load instead of a trilinear fetch. A null
// pointer disables its level.
struct SkipGrid {
  const std::uint8_t* empty = nullptr;
  int cellsX = 0, cellsY = 0, cellsZ = 0;
  int cellShift = 3;
  const std::uint32_t* fineEmpty = nullptr;
  int fineX = 0, fineY = 0, fineZ = 0;
  int fineShift = 2;
};

// Everything a ray needs that is the same for every pixel of a frame.
struct RayFrame {
  glm::vec3 eyeWorld{0.0f};
  glm::vec3 forward{0.0f};  // unit view direction
  glm::vec3 right{0.0f};    // unit right vector times tan(fovX / 2)
  glm::vec3 up{0.0f};       // unit up vector times tan(fovY / 2)
  glm::ivec2 screen{0, 0};  // full virtual screen in pixels
  glm::vec3 invSpacing{1.0f};
  glm::vec3 centerIndex{0.0f};  // index-space position of the world origin: (dims - 1) / 2
  glm::vec3 boxMax{0.0f};       // dims - 0.5 (the box minimum is -0.5)
  float stepWorld = 0.25f;      // step length in world units
  float earlyTermination = 0.995f;
  bool shading = false;
  // Shading gradients from the view's cell hook (GradientView) where it has one, else (and
  // when false) from six trilinear samples one voxel either side of the sample.
  bool cellGradients = true;
  // For views with mip levels (View::kTraversal): nearest-voxel sampling, and the ray's
  // footprint in voxels per world unit of t (0: always the finest level).
  bool nearest = false;
  float lodAngle = 0.0f;
  float ambient = 0.1f, diffuse = 0.7f, specular = 0.2f, shininess = 10.0f;
  int shininessInt = 10;  // shininess when it is a whole number in [0, 1024], else -1
};
static_assert(std::is_trivially_copyable_v<RayFrame>);
static_assert(std::is_trivially_copyable_v<SkipGrid>);

struct PixelResult {
  glm::vec4 rgba{0.0f};  // premultiplied colour and opacity
  std::uint32_t samples = 0;
};

// Ray parameter where o + t invD^-1 leaves the box [lo, hi) it is inside of (index space);
// invD holds 1/d per axis (+-inf where d is 0, which never wins the minimum).
VOXWALL_HD_INLINE float boxExit(const glm::vec3& o, const glm::vec3& invD, const glm::vec3& lo,
                                const glm::vec3& hi) {
  float t = INFINITY;
  for (int a = 0; a < 3; ++a) {
    const float ta = ((invD[a] > 0.0f ? hi[a] : lo[a]) - o[a]) * invD[a];
    t = ta < t ? ta : t;
  }
  return t;
}

// The shading gradient (world units) at p, right after view.sample(p, cache): from the view's
// cell hook (GradientView) where it has one and f.cellGradients, else from six trilinear samples
// one voxel either side of the sample (central differences over two voxels).
template <codec::kernels::VolumeView View>
VOXWALL_HD_INLINE glm::vec3 sampleGradient(const View& view, typename View::RayCache& cache,
                                           const RayFrame& f, const glm::vec3& p) {
  const glm::vec3 g = 0.5f * f.invSpacing;
  if constexpr (codec::kernels::GradientView<View>) {
    float d[3];
    if (f.cellGradients && view.gradient(p.x, p.y, p.z, cache, d))
      return glm::vec3(d[0], d[1], d[2]) * g;
  }
  return glm::vec3((view.sampleNear(p.x + 1.0f, p.y, p.z, cache) -
                    view.sampleNear(p.x - 1.0f, p.y, p.z, cache)) *
                       g.x,
                   (view.sampleNear(p.x, p.y + 1.0f, p.z, cache) -
                    view.sampleNear(p.x, p.y - 1.0f, p.z, cache)) *
                       g.y,
                   (view.sampleNear(p.x, p.y, p.z + 1.0f, cache) -
                    view.sampleNear(p.x, p.y, p.z - 1.0f, cache)) *
                       g.z);
}

// For a traversal view, after a transparent sample k: the next sample index to take, past the
// region around sample k where every sample has its value (cache.region*, for this level only),
// or k + 1 when the view reports none (Faas 2016, sections 3.2.2-3.2.4).
template <class Cache>
VOXWALL_HD_INLINE int regionEnd(const Cache& cache, const glm::vec3& o, const glm::vec3& invD,
                                const RayFrame& f, float tEnter, float invStep, int steps, int k) {
  if (!cache.regionValid) return k + 1;
  float tOut = boxExit(o, invD, glm::vec3(cache.regionLo[0], cache.regionLo[1], cache.regionLo[2]),
                       glm::vec3(cache.regionHi[0], cache.regionHi[1], cache.regionHi[2]));
  if (f.lodAngle > 0.0f) {  // the footprint picks another level from here on
    const float tLevel = cache.regionFootprintMax / f.lodAngle;
    tOut = tLevel < tOut ? tLevel : tOut;
  }
  const float kr = (tOut - tEnter) * invStep - 0.5f;
  const int kNext = kr >= float(steps) ? steps : codec::kernels::ceilToInt(kr);
  return kNext > k + 1 ? kNext : k + 1;
}

// Three and four values of a lane type (a vector and a colour per lane).
template <class F>
struct Lanes3 {
  F x, y, z;
};
template <class F>
struct Lanes4 {
  F r, g, b, a;
};

// The lane policy of raycastLanes for one ray at a time: a lane is a plain float, a mask a bool.
// CUDA (one thread per ray) and the CPU's scalar path run it. node/src/cpu_view_targets.hpp gives
// the same operations over SIMD vectors of neighbouring rays (Highway), so one body of per-ray
// code serves both: SPMD on SIMD, as ISPC and OSPRay do. Every operation keeps the scalar code's
// semantics (a ternary's NaN behaviour included), so the two paths give the same picture.
struct ScalarLanes {
  using F = float;
  using I = int;
  using M = bool;
  template <class View>
  using Caches = typename View::RayCache;

  static VOXWALL_HD_INLINE F splat(float v) { return v; }
  static VOXWALL_HD_INLINE I splatI(int v) { return v; }
  static VOXWALL_HD_INLINE F select(M m, F a, F b) { return m ? a : b; }
  static VOXWALL_HD_INLINE I selectI(M m, I a, I b) { return m ? a : b; }
  static VOXWALL_HD_INLINE M selectM(M m, M a, M b) { return m ? a : b; }
  static VOXWALL_HD_INLINE M both(M a, M b) { return a && b; }
  static VOXWALL_HD_INLINE M either(M a, M b) { return a || b; }
  static VOXWALL_HD_INLINE M butNot(M a, M b) { return a && !b; }
  static VOXWALL_HD_INLINE bool any(M m) { return m; }
  static VOXWALL_HD_INLINE M lessI(I a, I b) { return a < b; }
  static VOXWALL_HD_INLINE M isZeroI(I a) { return a == 0; }
  static VOXWALL_HD_INLINE F sqrt(F v) { return sqrtf(v); }
  static VOXWALL_HD_INLINE F abs(F v) { return fabsf(v); }
  static VOXWALL_HD_INLINE F pow(F v, float e) { return powf(v, e); }
  static VOXWALL_HD_INLINE F exp(F v) { return expf(v); }
  static VOXWALL_HD_INLINE I trunc(F v) { return int(v); }
  static VOXWALL_HD_INLINE F toFloat(I v) { return float(v); }
  static VOXWALL_HD_INLINE I shiftRight(I v, int s) { return v >> s; }
  static VOXWALL_HD_INLINE I ceilInt(F v) { return codec::kernels::ceilToInt(v); }
  // Where m: is base[index] non-zero (a skip grid's cell)?
  static VOXWALL_HD_INLINE M byteSet(const std::uint8_t* base, I index, M m) {
    return m && base[index] != 0;
  }
  // Where m: is bit `index` of the words set (bit index % 32 of word index / 32)?
  static VOXWALL_HD_INLINE M bitSet(const std::uint32_t* words, I index, M m) {
    return m && ((words[index >> 5] >> (index & 31)) & 1u) != 0;
  }
  static VOXWALL_HD_INLINE Lanes4<F> lookup(const TransferLut& lut, F value) {
    const glm::vec4 c = lut.lookup(value);
    return {c.r, c.g, c.b, c.a};
  }

  // The view, where m.
  template <class View>
  static VOXWALL_HD_INLINE F sample(const View& view, Caches<View>& cache, const Lanes3<F>& p, M) {
    return view.sample(p.x, p.y, p.z, cache);
  }
  template <class View>
  static VOXWALL_HD_INLINE Lanes3<F> gradient(const View& view, Caches<View>& cache,
                                              const RayFrame& f, const Lanes3<F>& p, M) {
    const glm::vec3 g = sampleGradient(view, cache, f, glm::vec3(p.x, p.y, p.z));
    return {g.x, g.y, g.z};
  }
  template <class View>
  static VOXWALL_HD_INLINE void setNearest(Caches<View>& cache, bool nearest) {
    cache.nearest = nearest;
  }
  template <class View>
  static VOXWALL_HD_INLINE void setFootprint(Caches<View>& cache, F footprint, M) {
    cache.footprint = footprint;
  }
  template <class View>
  static VOXWALL_HD_INLINE I regionEnd(const Caches<View>& cache, const glm::vec3& o,
                                       const Lanes3<F>& invD, const RayFrame& f, F tEnter,
                                       float invStep, I steps, I k, M) {
    return kernels::regionEnd(cache, o, glm::vec3(invD.x, invD.y, invD.z), f, tEnter, invStep,
                              steps, k);
  }
};

#include <voxwall/node/kernels/raycast_lanes.inl>  // LaneKernels: the code over lanes

// The same for one ray (what the kernel tests check).
VOXWALL_HD_INLINE glm::vec3 pixelDirection(const RayFrame& f, int px, int py) {
  const Lanes3<float> d = LaneKernels::pixelDirectionLanes<ScalarLanes>(f, px, py);
  return glm::vec3(d.x, d.y, d.z);
}
VOXWALL_HD_INLINE bool rayBox(const glm::vec3& o, const glm::vec3& d, const glm::vec3& lo,
                              const glm::vec3& hi, float& tEnter, float& tExit) {
  return LaneKernels::rayBoxLanes<ScalarLanes>(
      o, {d.x, d.y, d.z}, {1.0f / d.x, 1.0f / d.y, 1.0f / d.z}, lo, hi, true, tEnter, tExit);
}
VOXWALL_HD_INLINE void compositeOver(glm::vec4& acc, const glm::vec3& color, float alpha) {
  Lanes4<float> a{acc.r, acc.g, acc.b, acc.a};
  LaneKernels::compositeLanes<ScalarLanes>(a, {color.r, color.g, color.b}, alpha);
  acc = glm::vec4(a.r, a.g, a.b, a.a);
}
VOXWALL_HD_INLINE glm::vec3 shade(const glm::vec3& color, const glm::vec3& gradientWorld,
                                  const glm::vec3& dir, const RayFrame& f) {
  const Lanes3<float> c = LaneKernels::shadeLanes<ScalarLanes>(
      {color.r, color.g, color.b}, {gradientWorld.x, gradientWorld.y, gradientWorld.z},
      {dir.x, dir.y, dir.z}, f);
  return glm::vec3(c.x, c.y, c.z);
}

// Renders one pixel of the virtual screen: LaneKernels::raycastLanes for a single ray.
template <codec::kernels::VolumeView View>
VOXWALL_HD_INLINE PixelResult raycastPixel(const View& view, const RayFrame& f,
                                           const TransferLut& lut, const SkipGrid& skip, int px,
                                           int py) {
  Lanes4<float> acc;
  int samples;
  LaneKernels::raycastLanes<ScalarLanes>(view, f, lut, skip, px, py, true, acc, samples);
  PixelResult out;
  out.rgba = glm::vec4(acc.r, acc.g, acc.b, acc.a);
  out.samples = std::uint32_t(samples);
  return out;
}

// Premultiplied float RGBA to 8-bit, rounding to nearest.
VOXWALL_HD_INLINE std::uint32_t packRgba8(const glm::vec4& c) {
  auto q = [](float v) {
    v = v < 0.0f ? 0.0f : (v > 1.0f ? 1.0f : v);
    return std::uint32_t(v * 255.0f + 0.5f);
  };
  return q(c.r) | (q(c.g) << 8) | (q(c.b) << 16) | (q(c.a) << 24);
}

}  // namespace voxwall::node::kernels
