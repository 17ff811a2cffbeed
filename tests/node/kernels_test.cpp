// The per-ray code against hand-computed values.
#include <gtest/gtest.h>

#include <cmath>
#include <voxwall/codec/generators.hpp>
#include <voxwall/node/renderer.hpp>

using namespace voxwall;
using namespace voxwall::node;
using codec::kernels::RawView;

TEST(RayBox, HitsAlongAnAxis) {
  float t0, t1;
  ASSERT_TRUE(
      kernels::rayBox({-5, 0.2f, 0.3f}, {1, 0, 0}, glm::vec3(-0.5f), glm::vec3(9.5f), t0, t1));
  EXPECT_FLOAT_EQ(t0, 4.5f);
  EXPECT_FLOAT_EQ(t1, 14.5f);
}

TEST(RayBox, MissesParallelOutsideAndBehindCounts) {
  float t0, t1;
  EXPECT_FALSE(kernels::rayBox({-5, 20, 0}, {1, 0, 0}, glm::vec3(-0.5f), glm::vec3(9.5f), t0, t1));
  EXPECT_FALSE(kernels::rayBox({-5, -5, 0}, {1, -1, 0}, glm::vec3(-0.5f), glm::vec3(9.5f), t0, t1));
  // Origin inside: entry is behind the origin.
  ASSERT_TRUE(kernels::rayBox({1, 1, 1}, {0, 0, -2}, glm::vec3(0), glm::vec3(4), t0, t1));
  EXPECT_FLOAT_EQ(t0, -1.5f);
  EXPECT_FLOAT_EQ(t1, 0.5f);
}

TEST(RayBox, DiagonalThroughACube) {
  float t0, t1;
  const glm::vec3 d = glm::normalize(glm::vec3(1, 1, 1));
  ASSERT_TRUE(kernels::rayBox({-1, -1, -1}, d, glm::vec3(0), glm::vec3(1), t0, t1));
  EXPECT_NEAR(t0, std::sqrt(3.0f), 1e-5f);
  EXPECT_NEAR(t1, 2 * std::sqrt(3.0f), 1e-5f);
}

TEST(Compositing, FrontToBackOverByHand) {
  glm::vec4 acc(0.0f);
  kernels::compositeOver(acc, {1, 0, 0}, 0.5f);
  kernels::compositeOver(acc, {0, 1, 0}, 0.5f);
  // First red at 0.5, then green through the remaining 0.5 at 0.5: 0.25.
  EXPECT_FLOAT_EQ(acc.r, 0.5f);
  EXPECT_FLOAT_EQ(acc.g, 0.25f);
  EXPECT_FLOAT_EQ(acc.b, 0.0f);
  EXPECT_FLOAT_EQ(acc.a, 0.75f);
}

TEST(TransferLut, InterpolatesAndClamps) {
  HostLut lut;
  // Three entries and the guard entry repeating the last.
  lut.entries = {glm::vec4(0), glm::vec4(1, 0, 0, 0.5f), glm::vec4(0, 0, 1, 1),
                 glm::vec4(0, 0, 1, 1)};
  lut.lo = 10.0f;
  lut.hi = 30.0f;
  const auto v = lut.view();
  EXPECT_FLOAT_EQ(v.lookup(15.0f).a, 0.25f);
  EXPECT_FLOAT_EQ(v.lookup(25.0f).b, 0.5f);
  EXPECT_FLOAT_EQ(v.lookup(-100.0f).a, 0.0f);
  EXPECT_FLOAT_EQ(v.lookup(100.0f).a, 1.0f);
  EXPECT_FLOAT_EQ(lut.maxOpacity(0.0f, 10.0f), 0.0f);
  EXPECT_FLOAT_EQ(lut.maxOpacity(0.0f, 10.5f), 0.5f);  // reaches into the ramp
  EXPECT_FLOAT_EQ(lut.maxOpacity(21.0f, 22.0f), 1.0f);
}

namespace {

// A constant slab seen straight along x through the centre pixel of a 3x3 screen.
glm::vec4 slabPixel(glm::dvec3 spacing, float opacityPerVoxel, float stepVoxels) {
  codec::Volume v = codec::Volume::allocate({16, 5, 5}, codec::ScalarType::UInt8, spacing);
  for (auto& x : v.as<std::uint8_t>()) x = 100;
  v.computeRange();
  const auto volume = RenderVolume::fromVolume(v, 4);
  TransferFunction tf;
  tf.colors = {{0, 1, 0.5, 0.25}, {255, 1, 0.5, 0.25}};
  tf.opacities = {{0, opacityPerVoxel}, {255, opacityPerVoxel}};
  Orbit orbit;
  orbit.azimuthDeg = 0, orbit.elevationDeg = 0, orbit.distance = 3;
  RenderSettings settings;
  settings.stepVoxels = stepVoxels;
  const auto plan =
      planFrame(volume, orbitCamera(orbit, boundingRadius(volume.info())), 3, 3, tf, settings);
  const auto view = std::get<RawView<std::uint8_t>>(volume.view());
  return kernels::raycastPixel(view, plan.ray, plan.lut.view(), plan.skip, 1, 1).rgba;
}

}  // namespace

TEST(Raycast, ConstantSlabOpacityIsOneMinusExpMinusTauL) {
  const float a = 0.05f;
  const double tau = -std::log(1.0 - a);  // per voxel
  for (float step : {1.0f, 0.25f, 0.1f}) {
    const glm::vec4 c = slabPixel({1, 1, 1}, a, step);
    const double expected = 1.0 - std::exp(-tau * 16.0);
    EXPECT_NEAR(c.a, expected, 2e-4) << "step " << step;
    EXPECT_NEAR(c.r, expected * 1.0, 2e-4);  // premultiplied colour
    EXPECT_NEAR(c.g, expected * 0.5, 2e-4);
    EXPECT_NEAR(c.b, expected * 0.25, 2e-4);
  }
  // Twice the spacing along the ray: twice the physical length, twice the optical depth
  // (opacity is per voxel of the smallest spacing).
  const glm::vec4 stretched = slabPixel({2, 1, 1}, a, 0.25f);
  EXPECT_NEAR(stretched.a, 1.0 - std::exp(-tau * 32.0), 2e-4);
}

TEST(Raycast, EarlyTerminationStopsAtTheThreshold) {
  const glm::vec4 c = slabPixel({1, 1, 1}, 0.9f, 0.25f);
  EXPECT_GE(c.a, 0.995f);
  EXPECT_LT(c.a, 1.0f);  // stopped, not run to saturation
}

TEST(Shading, HeadlightOnAFacingSurfaceIsAmbientDiffuseSpecular) {
  kernels::RayFrame f;
  const glm::vec3 dir(0, 0, -1);
  const glm::vec3 c = kernels::shade({0.5f, 0.5f, 0.5f}, {0, 0, 3}, dir, f);
  EXPECT_NEAR(c.r, 0.5f * (0.1f + 0.7f) + 0.2f, 1e-6f);
  // Grazing light: ambient only.
  const glm::vec3 g = kernels::shade({0.5f, 0.5f, 0.5f}, {3, 0, 0}, dir, f);
  EXPECT_NEAR(g.r, 0.05f, 1e-6f);
  // No gradient: unshaded (ambient + diffuse).
  EXPECT_NEAR(kernels::shade({0.5f, 0.5f, 0.5f}, {0, 0, 0}, dir, f).r, 0.4f, 1e-6f);
}

TEST(TransferLut, RangeMaxTableAgreesWithAScan) {
  std::uint32_t seed = 12345;
  auto next = [&] { return (seed = seed * 1664525u + 1013904223u) >> 8; };
  for (int size : {2, 3, 17, 1000, 4096}) {
    HostLut scan;
    for (int i = 0; i < size; ++i)
      scan.entries.push_back(glm::vec4(0, 0, 0, float(next() % 100) / 100.0f));
    scan.entries.push_back(scan.entries.back());  // guard
    scan.lo = -5.0f;
    scan.hi = 20.0f;
    HostLut table = scan;
    table.buildRangeMax();
    for (int q = 0; q < 500; ++q) {
      const float a = -8.0f + float(next() % 3000) / 100.0f,
                  b = -8.0f + float(next() % 3000) / 100.0f;
      ASSERT_EQ(table.maxOpacity(a, b), scan.maxOpacity(a, b))
          << size << " [" << a << ", " << b << "]";
    }
  }
}

namespace {

// The segment from `front` to `back` (a step of `stepVoxels`) composited in 20000 sub-steps
// from the transfer function itself: premultiplied colour and opacity.
glm::dvec4 integrateSegment(const TransferFunction& tf, double front, double back,
                            double stepVoxels) {
  constexpr int kSub = 20000;
  glm::dvec4 acc(0.0);
  for (int i = 0; i < kSub; ++i) {
    double rgba[4];
    tf.evaluate(front + (back - front) * (i + 0.5) / kSub, rgba);
    const double a = 1.0 - std::pow(1.0 - rgba[3], stepVoxels / kSub);
    const double w = (1.0 - acc.a) * a;
    acc += glm::dvec4(w * rgba[0], w * rgba[1], w * rgba[2], w);
  }
  return acc;
}

glm::dvec4 preIntegrated(const HostLut& lut, float front, float back) {
  const auto view = lut.view();
  using L = kernels::ScalarLanes;
  const glm::vec4 p = view.lookup(back);
  const auto c = kernels::LaneKernels::segmentLanes<L>(view, front, back, {p.r, p.g, p.b, p.a});
  return glm::dvec4(c.r * c.a, c.g * c.a, c.b * c.a, c.a);  // premultiplied, as composited
}

}  // namespace

// Pre-integration against numeric integration of the same segment: a peak narrower than the
// segment's value span (which a sample at either end would miss), colour changing across it.
TEST(PreIntegration, MatchesNumericIntegrationOfTheSegment) {
  TransferFunction tf;
  tf.colors = {{0, 1, 0, 0}, {100, 0, 0, 1}};
  tf.opacities = {{0, 0}, {48, 0}, {50, 0.6}, {52, 0}, {100, 0}};
  for (const double step : {0.25, 1.0, 2.0}) {
    const HostLut lut = tf.bake(0, 100, step, 4096, true);
    for (const auto& [front, back] :
         {std::pair{30.0, 70.0}, {70.0, 30.0}, {49.0, 51.5}, {10.0, 20.0}, {50.0, 50.0}}) {
      const glm::dvec4 want = integrateSegment(tf, front, back, step);
      const glm::dvec4 got = preIntegrated(lut, float(front), float(back));
      SCOPED_TRACE(testing::Message() << "step " << step << ", " << front << " -> " << back);
      EXPECT_NEAR(got.a, want.a, 5e-3);  // the table's own resolution at the peak
      // The colour is the depth-weighted mean: it leaves out the segment's attenuation of its
      // own emission, a few percent of the opacity here.
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 0.03 * want.a + 2e-3);
    }
  }
  // Transparent on both sides of the peak, and no peak crossed: nothing at all.
  const HostLut lut = tf.bake(0, 100, 1.0, 4096, true);
  EXPECT_EQ(preIntegrated(lut, 10.0f, 40.0f).a, 0.0);
  EXPECT_GT(preIntegrated(lut, 10.0f, 90.0f).a, 0.01);  // crossed: a point sample misses it
  EXPECT_EQ(lut.view().lookup(10.0f).a + lut.view().lookup(90.0f).a, 0.0f);
}
