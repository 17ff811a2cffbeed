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

// Empty-space skipping in two levels, both x fastest, 1 = the transfer function is zero over
// the cell's value range (grown by one voxel): coarse cells of 2^cellShift voxels, which rays
// jump over, and fine cells of 2^fineShift voxels, checked per sample inside non-empty coarse
// cells so a transparent sample costs a byte load instead of a trilinear fetch. A null pointer
// disables its level.
struct SkipGrid {
  const std::uint8_t* empty = nullptr;
  int cellsX = 0, cellsY = 0, cellsZ = 0;
  int cellShift = 3;
  const std::uint8_t* fineEmpty = nullptr;
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

// Intersects o + t d with the box [lo, hi]; returns false when it misses. d may have zeros.
VOXWALL_HD_INLINE bool rayBox(const glm::vec3& o, const glm::vec3& d, const glm::vec3& lo,
                              const glm::vec3& hi, float& tEnter, float& tExit) {
  float t0 = -INFINITY, t1 = INFINITY;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0f) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    const float inv = 1.0f / d[a];
    float tn = (lo[a] - o[a]) * inv, tf = (hi[a] - o[a]) * inv;
    if (tn > tf) {
      const float s = tn;
      tn = tf, tf = s;
    }
    t0 = tn > t0 ? tn : t0;
    t1 = tf < t1 ? tf : t1;
  }
  tEnter = t0, tExit = t1;
  return t0 <= t1;
}

// Front-to-back "over" of a straight-colour sample with opacity alpha onto premultiplied acc.
VOXWALL_HD_INLINE void compositeOver(glm::vec4& acc, const glm::vec3& color, float alpha) {
  const float w = (1.0f - acc.a) * alpha;
  acc.r += w * color.r;
  acc.g += w * color.g;
  acc.b += w * color.b;
  acc.a += w;
}

// nl^shininess. An integer exponent (the default 10) is taken by repeated squaring, a few
// multiplies where powf is a library call of about a hundred instructions; the result is
// powf's to a few units in the last place.
VOXWALL_HD_INLINE float specularPower(float nl, const RayFrame& f) {
  if (f.shininessInt < 0) return powf(nl, f.shininess);
  float result = 1.0f, base = nl;
  for (int e = f.shininessInt; e; e >>= 1) {
    if (e & 1) result *= base;
    base *= base;
  }
  return result;
}

// Blinn-Phong with a headlight (light and viewer along -dir), two-sided, white specular.
VOXWALL_HD_INLINE glm::vec3 shade(const glm::vec3& color, const glm::vec3& gradientWorld,
                                  const glm::vec3& dir, const RayFrame& f) {
  const float len = sqrtf(glm::dot(gradientWorld, gradientWorld));
  if (!(len > 1e-12f)) return color * (f.ambient + f.diffuse);  // homogeneous: unshaded
  // |n . dir| with n = gradient / len, one division instead of normalizing (three); light =
  // viewer, so the halfway vector is the light.
  const float nl = fabsf(glm::dot(gradientWorld, dir)) / len;
  const float spec = f.specular * specularPower(nl, f);
  const glm::vec3 c = color * (f.ambient + f.diffuse * nl) + glm::vec3(spec);
  return glm::min(c, glm::vec3(1.0f));
}

// Unit world-space direction of the ray through the centre of pixel (px, py) of the virtual
// screen. Tiles use the same global pixel coordinates, so a tile's rays are the full render's.
VOXWALL_HD_INLINE glm::vec3 pixelDirection(const RayFrame& f, int px, int py) {
  const float sx = (float(px) + 0.5f) / float(f.screen.x) * 2.0f - 1.0f;
  const float sy = 1.0f - (float(py) + 0.5f) / float(f.screen.y) * 2.0f;
  return glm::normalize(f.forward + sx * f.right + sy * f.up);
}

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

// Composites one sample at index-space position p; returns true when the ray is opaque enough
// to stop. `transparent` tells whether the sample's opacity was zero.
template <codec::kernels::VolumeView View>
VOXWALL_HD_INLINE bool shadeAndComposite(const View& view, typename View::RayCache& cache,
                                         const RayFrame& f, const TransferLut& lut,
                                         const glm::vec3& p, const glm::vec3& dir, glm::vec4& acc,
                                         bool& transparent) {
  const glm::vec4 c = lut.lookup(view.sample(p.x, p.y, p.z, cache));
  transparent = c.a <= 0.0f;
  glm::vec3 color(c.r, c.g, c.b);
  // A transparent sample composites nothing; only the (costly) shading branches on it.
  if (f.shading && c.a > 0.0f) {
    const glm::vec3 g = 0.5f * f.invSpacing;  // central differences over two voxels, world units
    glm::vec3 grad;
    bool fromCell = false;
    if constexpr (codec::kernels::GradientView<View>) {
      float d[3];
      if (f.cellGradients && view.gradient(p.x, p.y, p.z, cache, d)) {
        grad = glm::vec3(d[0], d[1], d[2]) * g;
        fromCell = true;
      }
    }
    if (!fromCell)
      grad = glm::vec3((view.sampleNear(p.x + 1.0f, p.y, p.z, cache) -
                        view.sampleNear(p.x - 1.0f, p.y, p.z, cache)) *
                           g.x,
                       (view.sampleNear(p.x, p.y + 1.0f, p.z, cache) -
                        view.sampleNear(p.x, p.y - 1.0f, p.z, cache)) *
                           g.y,
                       (view.sampleNear(p.x, p.y, p.z + 1.0f, cache) -
                        view.sampleNear(p.x, p.y, p.z - 1.0f, cache)) *
                           g.z);
    color = shade(color, grad, dir, f);
  }
  compositeOver(acc, color, c.a);
  return acc.a >= f.earlyTermination;
}

// Renders one pixel of the virtual screen. `View` meets the view contract (VolumeView in
// view_concept.hpp: sample(x, y, z, RayCache&) is the trilinear sample in index space, the cache
// per-ray state the view may use to reuse work between consecutive samples, sampleNear the
// gradient's neighbours); its values are looked up in `lut`. Samples
// sit at t = tEnter + (k + 1/2) * stepWorld. With a skip grid the ray walks coarse cells: a
// cell's emptiness is looked up once per crossing and an empty cell is jumped over; inside a
// non-empty cell, a sample whose fine cell is empty is skipped (checked only after a transparent
// sample). A skipped sample would have had opacity exactly zero, and positions are computed from
// k, never accumulated, so the image is the same with and without skipping.
template <codec::kernels::VolumeView View>
VOXWALL_HD_INLINE PixelResult raycastPixel(const View& view, const RayFrame& f,
                                           const TransferLut& lut, const SkipGrid& skip, int px,
                                           int py) {
  PixelResult out;
  const glm::vec3 dir = pixelDirection(f, px, py);
  const glm::vec3 o = f.eyeWorld * f.invSpacing + f.centerIndex;
  const glm::vec3 d = dir * f.invSpacing;
  float tEnter, tExit;
  if (!rayBox(o, d, glm::vec3(-0.5f), f.boxMax, tEnter, tExit)) return out;
  tEnter = tEnter > 0.0f ? tEnter : 0.0f;
  if (tExit <= tEnter) return out;
  // Samples at (k + 1/2) steps that lie inside [tEnter, tExit); robust to rounding at the exit.
  const int steps = codec::kernels::ceilToInt((tExit - tEnter) / f.stepWorld - 0.5f);
  const float invStep = 1.0f / f.stepWorld;
  const glm::vec3 invD(1.0f / d.x, 1.0f / d.y, 1.0f / d.z);
  glm::vec4 acc(0.0f);
  bool transparent = true;        // was the last sample fully transparent?
  typename View::RayCache cache;  // the view's per-ray state (e.g. the last cell's corners)
  // Views that traverse a mip hierarchy (svmm) take the sampling mode and the ray's footprint,
  // and report the region around a sample where every sample has its value (a terminal block):
  // a transparent one is skipped in one step (Faas 2016, sections 3.2.2-3.2.4).
  constexpr bool traversal = requires { View::kTraversal; };
  static_assert(!traversal || codec::kernels::TraversalView<View>,
                "a view that declares kTraversal must meet TraversalView: its RayCache needs "
                "footprint, nearest, regionValid, regionLo/Hi and regionFootprintMax");
  if constexpr (traversal) cache.nearest = f.nearest;
  int k = 0;
  while (k < steps) {
    int kEnd = steps;
    if (skip.empty) {
      const glm::vec3 p = o + (tEnter + (float(k) + 0.5f) * f.stepWorld) * d;
      // The cell of the sample's lower trilinear corner: its range covers every voxel it reads.
      const int vx = p.x < 0.0f ? 0 : int(p.x), vy = p.y < 0.0f ? 0 : int(p.y),
                vz = p.z < 0.0f ? 0 : int(p.z);
      const int cx = vx >> skip.cellShift, cy = vy >> skip.cellShift, cz = vz >> skip.cellShift;
      const float size = float(1 << skip.cellShift);
      // Cell 0 also holds positions in [-0.5, 0): extend its lower bound.
      const glm::vec3 lo(cx ? float(cx) * size : -1.0f, cy ? float(cy) * size : -1.0f,
                         cz ? float(cz) * size : -1.0f);
      const glm::vec3 hi(float(cx + 1) * size, float(cy + 1) * size, float(cz + 1) * size);
      // First sample index at or past the cell's exit; at least the next one.
      const float kCell = (boxExit(o, invD, lo, hi) - tEnter) * invStep - 0.5f;
      kEnd = kCell >= float(steps) ? steps : codec::kernels::ceilToInt(kCell);
      kEnd = kEnd > k + 1 ? kEnd : k + 1;
      const bool inside = cx < skip.cellsX && cy < skip.cellsY && cz < skip.cellsZ;
      if (inside && skip.empty[(std::size_t(cz) * std::size_t(skip.cellsY) + std::size_t(cy)) *
                                   std::size_t(skip.cellsX) +
                               std::size_t(cx)]) {
        k = kEnd;
        continue;
      }
    }
    for (; k < kEnd; ++k) {
      const glm::vec3 p = o + (tEnter + (float(k) + 0.5f) * f.stepWorld) * d;
      // Fine cells are checked only after a transparent sample: inside opaque material they
      // would almost never skip, and the check costs as much as a tenth of a sample.
      if (skip.fineEmpty && transparent) {
        int fx = (p.x < 0.0f ? 0 : int(p.x)) >> skip.fineShift;
        int fy = (p.y < 0.0f ? 0 : int(p.y)) >> skip.fineShift;
        int fz = (p.z < 0.0f ? 0 : int(p.z)) >> skip.fineShift;
        fx = fx < skip.fineX ? fx : skip.fineX - 1;
        fy = fy < skip.fineY ? fy : skip.fineY - 1;
        fz = fz < skip.fineZ ? fz : skip.fineZ - 1;
        if (skip.fineEmpty[(std::size_t(fz) * std::size_t(skip.fineY) + std::size_t(fy)) *
                               std::size_t(skip.fineX) +
                           std::size_t(fx)])
          continue;
      }
      ++out.samples;
      if constexpr (traversal) {
        if (f.lodAngle > 0.0f)
          cache.footprint = (tEnter + (float(k) + 0.5f) * f.stepWorld) * f.lodAngle;
      }
      if (shadeAndComposite(view, cache, f, lut, p, dir, acc, transparent)) {
        out.rgba = acc;
        return out;
      }
      if constexpr (traversal) {
        if (transparent && cache.regionValid) {
          float tOut =
              boxExit(o, invD, glm::vec3(cache.regionLo[0], cache.regionLo[1], cache.regionLo[2]),
                      glm::vec3(cache.regionHi[0], cache.regionHi[1], cache.regionHi[2]));
          // The region holds for this level only: stop where the footprint picks another.
          if (f.lodAngle > 0.0f) {
            const float tLevel = cache.regionFootprintMax / f.lodAngle;
            tOut = tLevel < tOut ? tLevel : tOut;
          }
          // Samples before index kr lie inside the region: same value, also transparent.
          const float kr = (tOut - tEnter) * invStep - 0.5f;
          const int kNext = kr >= float(steps) ? steps : codec::kernels::ceilToInt(kr);
          if (kNext > k + 1) k = kNext - 1;
        }
      }
    }
  }
  out.rgba = acc;
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
