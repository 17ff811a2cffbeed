#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <stdexcept>
#include <voxwall/node/renderer.hpp>

namespace voxwall::node {

FramePlan planFrame(const RenderVolume& volume, const Camera& camera, int screenWidth,
                    int screenHeight, const TransferFunction& tf, const RenderSettings& settings) {
  if (screenWidth <= 0 || screenHeight <= 0)
    throw std::invalid_argument("screen size must be positive");
  if (!(settings.stepVoxels > 0)) throw std::invalid_argument("ray step must be positive");
  const auto& info = volume.info();
  FramePlan plan;
  auto& r = plan.ray;
  const glm::dvec3 forward = glm::normalize(camera.center - camera.eye);
  glm::dvec3 right = glm::cross(forward, camera.up);
  if (glm::length(right) < 1e-12)
    throw std::invalid_argument("camera up vector is parallel to the view");
  right = glm::normalize(right);
  const glm::dvec3 up = glm::cross(right, forward);
  const double tanY = std::tan(camera.fovYDeg * std::numbers::pi / 360.0);
  const double tanX = tanY * double(screenWidth) / double(screenHeight);
  r.eyeWorld = glm::vec3(camera.eye);
  r.forward = glm::vec3(forward);
  r.right = glm::vec3(right * tanX);
  r.up = glm::vec3(up * tanY);
  r.screen = {screenWidth, screenHeight};
  r.invSpacing = glm::vec3(1.0 / info.spacing);
  r.centerIndex = glm::vec3((glm::dvec3(info.dims) - 1.0) * 0.5);
  r.boxMax = glm::vec3(glm::dvec3(info.dims) - 0.5);
  const double minSpacing = std::min({info.spacing.x, info.spacing.y, info.spacing.z});
  r.stepWorld = float(settings.stepVoxels * minSpacing);
  r.earlyTermination = float(settings.earlyTerminationOpacity);
  r.shading = settings.shading;

  plan.lut = tf.bake(tf.domainMin(), tf.domainMax(), settings.stepVoxels, settings.lutEntries);

  const auto& ranges = volume.ranges();
  int shift = 0;
  while ((1 << shift) < ranges.cellVoxels) ++shift;
  if (settings.emptySpaceSkipping && (1 << shift) == ranges.cellVoxels && ranges.cellCount() > 0) {
    plan.emptyCells.resize(ranges.cellCount());
    std::size_t empty = 0;
    for (std::size_t c = 0; c < ranges.cellCount(); ++c) {
      plan.emptyCells[c] = plan.lut.maxOpacity(ranges.lo[c], ranges.hi[c]) <= 0.0f;
      empty += plan.emptyCells[c];
    }
    plan.emptyFraction = double(empty) / double(ranges.cellCount());
    plan.skip.empty = plan.emptyCells.data();
    plan.skip.cellsX = ranges.cells.x;
    plan.skip.cellsY = ranges.cells.y;
    plan.skip.cellsZ = ranges.cells.z;
    plan.skip.cellShift = shift;
  }
  return plan;
}

}  // namespace voxwall::node
