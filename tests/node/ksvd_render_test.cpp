// Rendering the ksvd codec's view against its decoded volume.
#include <gtest/gtest.h>

#include <cstdio>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"
#include "support/orbit_render.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::node;

// float32 data: the decoded volume holds exactly the values the view samples, so the images
// agree to a rounding step (see VqRender.LosslessRendersLikeRaw on fused multiply-adds).
TEST(KsvdRender, Float32RendersLikeItsDecodedVolumeForEveryBlockSide) {
  test::TempDir dir;
  const codec::Volume v = codec::generateMarschnerLobb(41, codec::ScalarType::Float32);
  const auto tf = TransferFunction::preset("cool-warm").rescaled(0, 1);
  for (int side : {4, 6, 8}) {
    codec::ksvd::Params p;
    p.blockSide = side, p.atoms = 48, p.sparsity = 5, p.iterations = 4;
    voxwall::Progress quiet;
    std::string name = "m";
    name += std::to_string(side);
    name += ".vwz";
    const std::string path = dir.path(name);
    codec::writeContainer(codec::ksvd::encode(v, p, quiet), path);
    const auto file = RenderVolume::open(path);
    EXPECT_EQ(file.info().codec, codec::ksvd::KsvdCodecEntry::kId);
    const auto container = codec::ContainerFile::open(path);
    const codec::Volume decoded = codec::ksvd::decode(container.info(), container.sections());
    const auto reference = RenderVolume::fromVolume(decoded);
    for (bool shading : {false, true}) {
      std::string label = "M";
      label += std::to_string(side);
      label += shading ? " shaded" : "";
      const Image expected = test::renderOrbit(reference, 64, 56, tf, shading);
      test::expectImagesNear(expected, test::renderOrbit(file, 64, 56, tf, shading), 1, 70, label);
      // Tiles on two threads share the per-thread block cache: the same pixels.
      test::expectImagesNear(expected,
                             test::renderOrbit(file, 64, 56, tf, shading, 2,
                                               {{0, 0, 40, 30}, {40, 0, 24, 30}, {0, 30, 64, 26}}),
                             1, 70, label + " tiles");
    }
  }
}

// Integer data: the decoded volume is rounded to the type, the view is not; the images stay
// close, and close to the raw render by about the PSNR the codec reports.
TEST(KsvdRender, Uint8RendersCloseToItsDecodedVolumeAndToRaw) {
  test::TempDir dir;
  const codec::Volume v = codec::generateSheppLogan(48);
  const auto tf = TransferFunction::preset("ct-soft").rescaled(0, 255);
  codec::ksvd::Params p;
  p.atoms = 64, p.sparsity = 8, p.iterations = 5;
  voxwall::Progress quiet;
  codec::ksvd::EncodeStats stats;
  codec::writeContainer(codec::ksvd::encode(v, p, quiet, &stats), dir.path("sl.vwz"));
  const auto file = RenderVolume::open(dir.path("sl.vwz"));
  const auto container = codec::ContainerFile::open(dir.path("sl.vwz"));
  const codec::Volume decoded = codec::ksvd::decode(container.info(), container.sections());
  EXPECT_DOUBLE_EQ(codec::psnr(v, decoded), stats.psnr);
  for (bool shading : {false, true}) {
    const Image image = test::renderOrbit(file, 64, 64, tf, shading);
    test::expectImagesNear(
        test::renderOrbit(RenderVolume::fromVolume(decoded), 64, 64, tf, shading), image, 12, 40,
        shading ? "shaded" : "unshaded");
    const double imagePsnr =
        voxwall::compareImages(test::renderOrbit(RenderVolume::fromVolume(v), 64, 64, tf, shading),
                               image)
            .psnrDb;
    std::printf("volume PSNR %.2f dB, image PSNR %.2f dB (%s)\n", stats.psnr, imagePsnr,
                shading ? "shaded" : "unshaded");
    EXPECT_GT(imagePsnr, 20);
  }
}

// The pyramid, against svmm's: with 2-voxel blocks and lossless values, an svmm file holds the
// same levels (each the mean of the 2x2x2 voxels below, 96, 48 and 24 voxels wide) and picks
// them by the same footprint rule, so its --lod and nearest renders are an independent reference
// for ksvd's, within ksvd's coding error (near-lossless here, so gradients agree too). At full size
// the footprint is below two voxels and
// --lod reads level 0 only: the same pixels as without it.
TEST(KsvdRender, LevelOfDetailAndNearestSamplingMatchSvmmsLevels) {
  test::TempDir dir;
  const codec::Volume v = codec::generateMarschnerLobb(96);
  const auto tf = TransferFunction::preset("cool-warm").rescaled(0, 255);
  codec::ksvd::Params p;
  p.blockSide = 4, p.atoms = 256, p.sparsity = 48, p.iterations = 1;  // near-lossless
  voxwall::Progress quiet;
  codec::ksvd::EncodeStats stats;
  codec::writeContainer(codec::ksvd::encode(v, p, quiet, &stats), dir.path("ml.vwz"));
  ASSERT_EQ(stats.levels, 3);  // 96, 48, 24 voxels at bricks of 32
  codec::svmm::Params sp;
  sp.blockWidth = 2, sp.rootWidth = 32, sp.quality = 100;
  codec::writeContainer(codec::svmm::encode(v, sp, quiet), dir.path("svmm.vwz"));
  const auto ksvd = RenderVolume::open(dir.path("ml.vwz"));
  const auto svmm = RenderVolume::open(dir.path("svmm.vwz"));
  EXPECT_TRUE(ksvd.traversal());
  struct Case {
    const char* label;
    int w, h;
    bool lod, nearest, shading;
  };
  for (const Case& c : {Case{"fine 16x12", 16, 12, false, false, false},
                        Case{"lod 16x12", 16, 12, true, false, false},
                        Case{"lod 16x12 shaded", 16, 12, true, false, true},
                        Case{"fine 16x12 shaded", 16, 12, false, false, true},
                        Case{"lod 40x30 shaded", 40, 30, true, false, true},
                        Case{"lod 32x24 nearest", 32, 24, true, true, false},
                        Case{"nearest 64x48", 64, 48, false, true, false},
                        Case{"nearest 64x48 shaded", 64, 48, false, true, true}}) {
    RenderSettings s;
    s.levelOfDetail = c.lod, s.nearest = c.nearest, s.shading = c.shading;
    const Image a = test::renderOrbit(ksvd, c.w, c.h, tf, s);
    const Image b = test::renderOrbit(svmm, c.w, c.h, tf, s);
    const auto cmp = voxwall::compareImages(b, a);
    std::printf("%s: ksvd against svmm %.2f dB, max %d\n", c.label, cmp.psnrDb, cmp.maxAbs);
    EXPECT_GT(cmp.psnrDb, 40.0) << c.label;  // ignoring --lod or nearest gives 11-20 dB
  }
  // The coarse levels were used, and at full size they are not.
  RenderSettings fine, lod;
  lod.levelOfDetail = true;
  EXPECT_GT(voxwall::compareImages(test::renderOrbit(ksvd, 16, 12, tf, fine),
                                   test::renderOrbit(ksvd, 16, 12, tf, lod))
                .maxAbs,
            0);
  test::expectImagesNear(test::renderOrbit(ksvd, 200, 150, tf, fine),
                         test::renderOrbit(ksvd, 200, 150, tf, lod), 0, 0.0, "full size");
}
