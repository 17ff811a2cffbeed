#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <stdexcept>
#include <voxwall/node/camera.hpp>

namespace voxwall::node {

Camera orbitCamera(const Orbit& orbit, double boundingRadius) {
  const double d2r = std::numbers::pi / 180.0;
  const double az = orbit.azimuthDeg * d2r, el = orbit.elevationDeg * d2r;
  Camera c;
  c.center = {0, 0, 0};
  const double r = orbit.distance * boundingRadius;
  c.eye = {r * std::cos(el) * std::cos(az), r * std::cos(el) * std::sin(az), r * std::sin(el)};
  // Straight up or down, +z is parallel to the view: use the azimuth direction instead.
  c.up = std::abs(std::cos(el)) < 1e-6 ? glm::dvec3(-std::cos(az), -std::sin(az), 0)
                                       : glm::dvec3(0, 0, 1);
  c.fovYDeg = orbit.fovYDeg;
  if (orbit.panX != 0 || orbit.panY != 0) {
    const glm::dvec3 forward = glm::normalize(c.center - c.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, c.up));
    const glm::dvec3 up = glm::cross(right, forward);
    const glm::dvec3 offset = (right * orbit.panX + up * orbit.panY) * boundingRadius;
    c.eye += offset;
    c.center += offset;
  }
  return c;
}

namespace {
struct NamedView {
  const char* name;
  ViewAngles angles;
};
constexpr NamedView kViews[] = {
    {"anterior", {-90, 0}}, {"posterior", {90, 0}}, {"left", {0, 0}},
    {"right", {180, 0}},    {"superior", {90, 90}}, {"inferior", {90, -90}},
};
}  // namespace

std::optional<ViewAngles> anatomicalView(std::string_view name) {
  for (const NamedView& v : kViews)
    if (name == v.name) return v.angles;
  return std::nullopt;
}

std::string anatomicalViewNames() {
  std::string out;
  for (const NamedView& v : kViews) out += (out.empty() ? "" : ", ") + std::string(v.name);
  return out;
}

Frustum tileFrustum(const Camera& camera, int screenWidth, int screenHeight, const Rect& tile,
                    double nearDist, double farDist) {
  if (tile.width <= 0 || tile.height <= 0 || screenWidth <= 0 || screenHeight <= 0)
    throw std::invalid_argument("tileFrustum: empty tile or screen");
  const double tanY = std::tan(camera.fovYDeg * std::numbers::pi / 360.0);
  const double tanX = tanY * double(screenWidth) / double(screenHeight);
  auto sx = [&](int px) { return (double(px) / screenWidth * 2.0 - 1.0) * tanX * nearDist; };
  auto sy = [&](int py) { return (1.0 - double(py) / screenHeight * 2.0) * tanY * nearDist; };
  return {sx(tile.x), sx(tile.x + tile.width), sy(tile.y + tile.height), sy(tile.y), nearDist,
          farDist};
}

}  // namespace voxwall::node
