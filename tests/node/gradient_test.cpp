// The views' cell-gradient hook (GradientView) against the six trilinear samples it replaces:
// the same gradient, to rounding, for every codec, along rays that revisit and leave cells (so a
// stale cached cell would show) and cross the volume's outer half voxel.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <variant>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/kernels/view_concept.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/orbit_render.hpp"

using namespace voxwall;
using namespace voxwall::node;

namespace {

const std::string kReferenceDir = std::string(VOXWALL_TEST_DATA_DIR) + "/reference/";

// Walks `rays` random rays through the volume at a quarter-voxel step; at every sample compares
// the hook's gradient with the six-sample one. Returns how many samples the hook answered.
template <class View>
int compareAlongRays(const View& view, int rays, float scale) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float hi[3] = {float(view.dimX - 1), float(view.dimY - 1), float(view.dimZ - 1)};
  int answered = 0;
  for (int r = 0; r < rays; ++r) {
    float p[3], d[3];
    for (int a = 0; a < 3; ++a) p[a] = u(rng) * (hi[a] + 1.0f) - 0.5f, d[a] = u(rng) * 2.0f - 1.0f;
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    typename View::RayCache cache;
    for (int k = 0; k < 400; ++k) {
      for (int a = 0; a < 3; ++a) p[a] += 0.25f * d[a] / len;
      // Through the outer half voxel too, where the hooks hand back to the six samples.
      if (p[0] < -0.5f || p[1] < -0.5f || p[2] < -0.5f || p[0] > hi[0] + 0.5f ||
          p[1] > hi[1] + 0.5f || p[2] > hi[2] + 0.5f)
        break;
      // Now and then a voxel centre or a cell face exactly.
      float q[3] = {p[0], p[1], p[2]};
      if (k % 37 == 5) q[k % 3] = std::floor(q[k % 3]);
      view.sample(q[0], q[1], q[2], cache);
      float g[3];
      if (!view.gradient(q[0], q[1], q[2], cache, g)) {
        // Only the outer half voxel (and, for svmm and ksvd, coarse levels) hands back.
        EXPECT_TRUE(q[0] < 0 || q[1] < 0 || q[2] < 0 || q[0] > hi[0] || q[1] > hi[1] ||
                    q[2] > hi[2]);
        continue;
      }
      ++answered;
      typename View::RayCache other;
      const float six[3] = {view.sampleNear(q[0] + 1, q[1], q[2], other) -
                                view.sampleNear(q[0] - 1, q[1], q[2], other),
                            view.sampleNear(q[0], q[1] + 1, q[2], other) -
                                view.sampleNear(q[0], q[1] - 1, q[2], other),
                            view.sampleNear(q[0], q[1], q[2] + 1, other) -
                                view.sampleNear(q[0], q[1], q[2] - 1, other)};
      for (int a = 0; a < 3; ++a)
        if (std::fabs(g[a] - six[a]) > 1e-4f * scale) {
          ADD_FAILURE() << "ray " << r << " sample " << k << " at (" << q[0] << ", " << q[1] << ", "
                        << q[2] << ") axis " << a << ": cell " << g[a] << ", six samples "
                        << six[a];
          return answered;
        }
    }
  }
  return answered;
}

// The view types the volumes below produce: compareAlongRays is compiled for these only (every
// view type of every codec would make this file the slowest of the build).
template <class... Views>
void compareTheViewOf(const RenderVolume& volume, float scale) {
  const ViewVariant view = volume.view();
  const bool covered = (([&] {
                          const auto* v = std::get_if<Views>(&view);
                          if (v) {
                            EXPECT_GT(compareAlongRays(*v, 300, scale), 5000);
                          }
                          return v != nullptr;
                        }()) ||
                        ...);
  EXPECT_TRUE(covered) << "view type " << view.index() << " is not one this test compiles";
}

void expectHookMatchesSixSamples(const RenderVolume& volume, float scale) {
  namespace k = codec::kernels;
  compareTheViewOf<k::RawView<std::uint8_t>, k::RawView<float>, k::VqView, k::SvmmView,
                   k::KsvdView6>(volume, scale);
}

}  // namespace

TEST(CellGradients, RawViewsMatchSixSamples) {
  // 8^3 bricks: more than half of the cells ((6/8)^3 in-brick) read voxels outside their brick.
  expectHookMatchesSixSamples(RenderVolume::fromVolume(codec::generateMarschnerLobb(41), 8), 255);
  expectHookMatchesSixSamples(
      RenderVolume::fromVolume(codec::generateMarschnerLobb(23, codec::ScalarType::Float32), 16),
      1);
  expectHookMatchesSixSamples(RenderVolume::fromVolume(codec::generateSheppLogan(37), 16), 255);
}

TEST(CellGradients, CompressedViewsMatchSixSamples) {
  for (const char* codec : {"vq", "svmm", "ksvd"}) {
    SCOPED_TRACE(codec);
    expectHookMatchesSixSamples(RenderVolume::open(kReferenceDir + "phantom64_" + codec + ".vwz"),
                                255);
  }
}

TEST(CellGradients, ShadedFramesMatchTheSixSampleFramesForEveryCodec) {
  const auto tf = TransferFunction::preset("ct-soft").rescaled(0, 255);
  for (const char* codec : {"raw", "vq", "svmm", "ksvd"}) {
    SCOPED_TRACE(codec);
    const RenderVolume volume =
        std::string(codec) == "raw"
            ? RenderVolume::fromVolume(codec::generateMarschnerLobb(41), 8)
            : RenderVolume::open(kReferenceDir + "phantom64_" + codec + ".vwz");
    Image frame[2];
    for (int cell = 0; cell < 2; ++cell) {
      RenderSettings settings;
      settings.shading = true;
      settings.cellGradients = cell == 1;
      frame[cell] = test::renderOrbit(volume, 96, 72, tf, settings);
    }
    const ImageDiff d = compareImages(frame[0], frame[1]);
    EXPECT_LE(d.maxAbs, 2);
    EXPECT_GT(d.psnrDb, 50.0);
  }
}
