// Small scenes the renderer's tests share: volumes with their transfer functions, a close
// camera, whole and tiled renders, the converged reference and PSNR over the four channels.
#pragma once

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>
#include <voxwall/codec/generators.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::test {

using node::Camera, node::Orbit, node::RenderSettings, node::RenderVolume, node::TileStats,
    node::TransferFunction;

struct Scene {
  std::string name;
  RenderVolume volume;
  TransferFunction tf;
};

inline const Scene& phantomScene() {
  static const Scene s{"phantom", RenderVolume::fromVolume(codec::generateSheppLogan(48), 8),
                       TransferFunction::preset("ct-soft").rescaled(0, 255)};
  return s;
}

inline const Scene& marschnerLobbScene() {
  static const Scene s{"marschner-lobb",
                       RenderVolume::fromVolume(codec::generateMarschnerLobb(41), 8),
                       TransferFunction::preset("mri").rescaled(0, 255)};
  return s;
}

// A plane one voxel thick in an empty volume, tilted so it crosses the voxel grid: the thinnest
// feature a volume holds.
inline const Scene& thinPlaneScene() {
  static const Scene s = [] {
    const int n = 40;
    codec::Volume v = codec::Volume::allocate({n, n, n}, codec::ScalarType::UInt8);
    for (int z = 0; z < n; ++z)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
          v.as<std::uint8_t>()[v.index(x, y, z)] = std::abs(x + y / 3 - 26) == 0 ? 255 : 0;
    v.computeRange();
    return Scene{"thin plane", RenderVolume::fromVolume(v, 8),
                 TransferFunction::preset("grey").rescaled(0, 255)};
  }();
  return s;
}

inline Camera closeCamera(const RenderVolume& volume, double distance = 1.5) {
  Orbit o;
  o.azimuthDeg = 35, o.elevationDeg = 25, o.distance = distance;
  return node::orbitCamera(o, node::boundingRadius(volume.info()));
}

inline Image renderTiles(const Scene& scene, const Camera& camera, int w, int h,
                         const RenderSettings& settings, int threads,
                         const std::vector<Rect>& tiles, TileStats* total = nullptr) {
  auto backend = node::makeCpuBackend(threads);
  const node::FramePlan plan = node::planFrame(scene.volume, camera, w, h, scene.tf, settings);
  Image full(w, h), tile;
  for (const Rect& r : tiles) {
    const TileStats stats = backend->render(scene.volume, plan, r, tile);
    if (total) total->rays += stats.rays, total->samples += stats.samples;
    full.paste(tile, r);
  }
  return full;
}

inline Image renderWhole(const Scene& scene, const Camera& camera, int w, int h,
                         const RenderSettings& settings, TileStats* total = nullptr) {
  return renderTiles(scene, camera, w, h, settings, 2, {{0, 0, w, h}}, total);
}

// The converged reference: a ray a pixel at 1/8 voxel.
inline Image reference(const Scene& scene, const Camera& camera, int w, int h, bool shading) {
  RenderSettings s;
  s.latticeStride = 1;
  s.stepVoxels = 0.125;
  s.shading = shading;
  return renderWhole(scene, camera, w, h, s);
}

inline double psnr(const Image& a, const Image& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i)
    for (int shift = 0; shift < 32; shift += 8) {
      const double d =
          double((a.pixels[i] >> shift) & 255u) - double((b.pixels[i] >> shift) & 255u);
      sum += d * d;
    }
  const double mse = sum / (4.0 * double(a.pixels.size()));
  return mse == 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

}  // namespace voxwall::test
