#include <gtest/gtest.h>

#include <glm/geometric.hpp>
#include <voxwall/node/renderer.hpp>

using namespace voxwall::node;

TEST(Camera, OrbitLooksAtTheCentreFromTheGivenDistance) {
  Orbit o;
  o.azimuthDeg = 90, o.elevationDeg = 0, o.distance = 2;
  const Camera c = orbitCamera(o, 10.0);
  EXPECT_NEAR(c.eye.x, 0.0, 1e-12);
  EXPECT_NEAR(c.eye.y, 20.0, 1e-12);
  EXPECT_NEAR(glm::length(c.eye - c.center), 20.0, 1e-12);
  o.elevationDeg = 90;  // straight down: up must not be parallel to the view
  const Camera top = orbitCamera(o, 1.0);
  EXPECT_GT(glm::length(glm::cross(top.center - top.eye, top.up)), 0.5);
}

TEST(Camera, TileFrustumsPartitionTheFullFrustum) {
  Camera c;
  const Frustum full = tileFrustum(c, 1000, 500, {0, 0, 1000, 500}, 1.0, 10.0);
  EXPECT_NEAR(full.left, -full.right, 1e-12);
  EXPECT_NEAR(full.bottom, -full.top, 1e-12);
  EXPECT_NEAR(full.right / full.top, 2.0, 1e-12);  // aspect
  const Frustum a = tileFrustum(c, 1000, 500, {0, 0, 300, 500}, 1.0, 10.0);
  const Frustum b = tileFrustum(c, 1000, 500, {300, 0, 700, 200}, 1.0, 10.0);
  EXPECT_DOUBLE_EQ(a.left, full.left);
  EXPECT_DOUBLE_EQ(a.right, b.left);  // neighbours share their edge
  EXPECT_DOUBLE_EQ(b.right, full.right);
  EXPECT_DOUBLE_EQ(b.top, full.top);
  EXPECT_THROW(tileFrustum(c, 1000, 500, {0, 0, 0, 5}, 1, 2), std::invalid_argument);
}

TEST(Camera, PixelRaysLieInsideTheirTilesFrustum) {
  voxwall::codec::Volume v =
      voxwall::codec::Volume::allocate({4, 4, 4}, voxwall::codec::ScalarType::UInt8);
  const auto volume = RenderVolume::fromVolume(v, 4);
  Camera c = orbitCamera({}, 1.0);
  const auto plan = planFrame(volume, c, 64, 48, TransferFunction::preset("grey"), {});
  const voxwall::Rect tile{16, 8, 20, 10};
  const Frustum f = tileFrustum(c, 64, 48, tile, 1.0, 10.0);
  for (int y = tile.y; y < tile.y + tile.height; ++y)
    for (int x = tile.x; x < tile.x + tile.width; ++x) {
      const glm::vec3 d = kernels::pixelDirection(plan.ray, x, y);
      const float along = glm::dot(d, plan.ray.forward);
      const float sx = glm::dot(d, glm::normalize(plan.ray.right)) / along;
      const float sy = glm::dot(d, glm::normalize(plan.ray.up)) / along;
      EXPECT_GT(sx, f.left);
      EXPECT_LT(sx, f.right);
      EXPECT_GT(sy, f.bottom);
      EXPECT_LT(sy, f.top);
    }
}
