#include "support/orbit_render.hpp"

namespace voxwall::test {

voxwall::Image renderOrbit(const node::RenderVolume& volume, int w, int h,
                           const node::TransferFunction& tf, bool shading, int threads,
                           const std::vector<voxwall::Rect>& tiles) {
  node::RenderSettings s;
  s.shading = shading;
  return renderOrbit(volume, w, h, tf, s, threads, tiles);
}

voxwall::Image renderOrbit(const node::RenderVolume& volume, int w, int h,
                           const node::TransferFunction& tf, const node::RenderSettings& s,
                           int threads, const std::vector<voxwall::Rect>& tiles) {
  node::Orbit o;
  o.azimuthDeg = 35, o.elevationDeg = 25;
  const node::Camera camera = node::orbitCamera(o, node::boundingRadius(volume.info()));
  auto backend = node::makeCpuBackend(threads);
  const auto plan = node::planFrame(volume, camera, w, h, tf, s);
  voxwall::Image full(w, h), tile;
  for (const auto& r : tiles.empty() ? std::vector<voxwall::Rect>{{0, 0, w, h}} : tiles) {
    backend->render(volume, plan, r, tile);
    full.paste(tile, r);
  }
  return full;
}

}  // namespace voxwall::test
