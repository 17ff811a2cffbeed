// The ray's march from an error budget (node/march_budget.hpp) and the pre-integrated march it
// may pick: the budget met against a converged render, the same picture with and without
// empty-space skipping, for every cut and thread count, and from SIMD packets as from one ray.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/node/march_budget.hpp>

#include "support/image_expect.hpp"
#include "support/render_scenes.hpp"

using namespace voxwall;
using namespace voxwall::node;
using test::Scene, test::phantomScene, test::marschnerLobbScene, test::closeCamera,
    test::renderTiles, test::renderWhole, test::reference, test::psnr;

namespace {

RenderSettings preIntegrated(double step, bool shading) {
  RenderSettings s;
  s.stepVoxels = step;
  s.preIntegrate = true;
  s.shading = shading;
  s.latticeStride = 1;
  return s;
}

// The march picked for the scene's close view on a w x h screen, and the frame it renders
// (with the default ray lattice) against the converged render.
double pickedFramePsnr(const Scene& scene, const Camera& camera, int w, int h, bool shading,
                       MarchChoice& choice) {
  RenderSettings s;
  s.shading = shading;
  s.marchIntegration = MarchIntegration::Either;
  auto backend = makeCpuBackend(2);
  choice = chooseMarch(*backend, scene.volume, camera, w, h, scene.tf, s, kDefaultErrorBudgetDb);
  s.stepVoxels = choice.stepVoxels, s.preIntegrate = choice.preIntegrate;
  return psnr(renderWhole(scene, camera, w, h, s), reference(scene, camera, w, h, shading));
}

}  // namespace

// Skipped samples would have composited nothing: a pre-integrated segment is skipped only
// between two samples in empty cells, so the picture is the one without skipping.
TEST(PreIntegratedMarch, SkippingLeavesThePictureAsItIs) {
  for (const Scene* scene : {&phantomScene(), &marschnerLobbScene()})
    for (const double step : {0.5, 1.0, 2.0}) {
      const Camera camera = closeCamera(scene->volume);
      RenderSettings s = preIntegrated(step, true);
      TileStats skipping, all;
      const Image a = renderWhole(*scene, camera, 160, 120, s, &skipping);
      s.emptySpaceSkipping = false;
      const Image b = renderWhole(*scene, camera, 160, 120, s, &all);
      test::expectImagesNear(b, a, 0, 0, scene->name + ", step " + std::to_string(step));
      EXPECT_LT(skipping.samples, all.samples) << scene->name;
    }
}

TEST(PreIntegratedMarch, ThePictureIsTheSameForEveryCutAndThreadCount) {
  const Scene& scene = phantomScene();
  const Camera camera = closeCamera(scene.volume);
  const int w = 203, h = 157;
  const RenderSettings s = preIntegrated(1.0, true);
  const Image whole = renderTiles(scene, camera, w, h, s, 1, {{0, 0, w, h}});
  const std::vector<Rect> odd = {
      {0, 0, 77, 61}, {77, 0, 126, 61}, {0, 61, 13, 96}, {13, 61, 190, 3}, {13, 64, 190, 93}};
  test::expectImagesNear(whole, renderTiles(scene, camera, w, h, s, 3, odd), 0, 0, "odd tiles");
}

// SIMD packets (Highway's exp) and one ray at a time (expf) within the packets' usual tolerance.
TEST(PreIntegratedMarch, PacketsGiveThePictureOfOneRayAtATime) {
  const Scene& scene = marschnerLobbScene();
  const Camera camera = closeCamera(scene.volume);
  const int w = 160, h = 120;
  const RenderSettings s = preIntegrated(0.75, true);
  const FramePlan plan = planFrame(scene.volume, camera, w, h, scene.tf, s);
  Image packets, single;
  makeCpuBackend(2, true)->render(scene.volume, plan, {0, 0, w, h}, packets);
  makeCpuBackend(2, false)->render(scene.volume, plan, {0, 0, w, h}, single);
  test::expectImagesNear(single, packets, 2, 0, "pre-integrated, packets");
}

// A transfer function that is one thin peak: stepping a voxel at points misses much of it,
// pre-integrated segments do not.
TEST(PreIntegratedMarch, KeepsAThinPeakOfTheTransferFunctionAtALongStep) {
  Scene scene{"phantom, thin peak", RenderVolume::fromVolume(codec::generateSheppLogan(48), 8), {}};
  scene.tf.colors = {{0, 1, 0.9, 0.7}, {255, 1, 0.9, 0.7}};
  scene.tf.opacities = {{0, 0}, {120, 0}, {125, 0.9}, {130, 0}, {255, 0}};
  const Camera camera = closeCamera(scene.volume);
  const int w = 200, h = 150;
  const Image converged = reference(scene, camera, w, h, false);
  RenderSettings s = preIntegrated(1.0, false);
  const double pre = psnr(renderWhole(scene, camera, w, h, s), converged);
  s.preIntegrate = false;
  const double point = psnr(renderWhole(scene, camera, w, h, s), converged);
  std::printf("thin peak at a 1-voxel step: pre-integrated %.2f dB, at points %.2f dB\n", pre,
              point);
  EXPECT_GT(pre, point + 3.0);
}

// The picked march keeps the frame (with the ray lattice) within the budget of the converged
// render, shaded and not; where no march longer than a quarter voxel meets it (the phantom's
// hard edges, and shaded Marschner-Lobb), the frame is a quarter voxel's, as --exact's.
TEST(MarchBudget, TheFrameStaysWithinTheBudgetOrTakesAQuarterVoxel) {
  for (const Scene* scene : {&phantomScene(), &marschnerLobbScene()})
    for (const bool shading : {false, true}) {
      MarchChoice choice;
      const Camera camera = closeCamera(scene->volume);
      const double frame = pickedFramePsnr(*scene, camera, 640, 480, shading, choice);
      const std::string label = scene->name + (shading ? ", shaded" : "");
      std::printf("%s: step %g%s (probe %.2f dB), frame %.2f dB\n", label.c_str(),
                  choice.stepVoxels, choice.preIntegrate ? " pre-integrated" : "",
                  choice.probePsnrDb, frame);
      if (choice.stepVoxels > 0.25) {
        EXPECT_GE(choice.probePsnrDb, kDefaultErrorBudgetDb + kMarchMarginDb) << label;
        EXPECT_GE(frame, kDefaultErrorBudgetDb) << label;
      } else {
        EXPECT_EQ(choice.stepVoxels, 0.25) << label;
        EXPECT_FALSE(choice.preIntegrate) << label;
        RenderSettings exact;
        exact.shading = shading;
        exact.latticeStride = 1;
        const Image converged = reference(*scene, camera, 640, 480, shading);
        EXPECT_GE(frame, psnr(renderWhole(*scene, camera, 640, 480, exact), converged) - 1.5)
            << label;
      }
    }
  MarchChoice choice;
  const Scene& ml = marschnerLobbScene();
  (void)pickedFramePsnr(ml, closeCamera(ml.volume), 640, 480, false, choice);
  EXPECT_GT(choice.stepVoxels, 0.25);  // one that does take a longer step
}

TEST(MarchBudget, TheMriStaysWithinTheBudget) {
  const std::string path = "/usr/share/mricron/templates/ch2better.nii.gz";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not installed (mricron-data)";
  const Scene scene{"mri", RenderVolume::fromVolume(codec::readVolume(path)),
                    TransferFunction::preset("mri").rescaled(0, 130)};
  Orbit o;
  o.azimuthDeg = 30, o.elevationDeg = 20;
  const Camera camera = orbitCamera(o, boundingRadius(scene.volume.info()));
  for (const bool shading : {false, true}) {
    MarchChoice choice;
    const double frame = pickedFramePsnr(scene, camera, 960, 720, shading, choice);
    std::printf("mri%s: step %g%s, frame %.2f dB\n", shading ? ", shaded" : "", choice.stepVoxels,
                choice.preIntegrate ? " pre-integrated" : "", frame);
    EXPECT_GE(frame, kDefaultErrorBudgetDb);
    EXPECT_GT(choice.stepVoxels, 0.25);  // the budget buys a longer step than --exact's
  }
}

TEST(MarchBudget, AStricterBudgetTakesAShorterStep) {
  const Scene& scene = phantomScene();
  RenderSettings s;
  s.marchIntegration = MarchIntegration::Either;
  auto backend = makeCpuBackend(2);
  const Camera camera = closeCamera(scene.volume);
  const MarchChoice loose = chooseMarch(*backend, scene.volume, camera, 640, 480, scene.tf, s, 35);
  const MarchChoice strict = chooseMarch(*backend, scene.volume, camera, 640, 480, scene.tf, s, 80);
  EXPECT_GT(loose.stepVoxels, strict.stepVoxels);
  EXPECT_EQ(strict.stepVoxels, 0.25);  // none meets 83 dB: the quarter voxel
  EXPECT_FALSE(strict.preIntegrate);
  int w = 0, h = 0;
  probeScreen(5772, 4338, w, h);
  EXPECT_LE(w * h, 97000);
  EXPECT_NEAR(double(w) / h, 5772.0 / 4338.0, 0.01);
  probeScreen(200, 100, w, h);  // small screens are probed whole
  EXPECT_EQ(w, 200);
  EXPECT_EQ(h, 100);
}
