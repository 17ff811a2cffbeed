// Rendering the vq codec's view against the raw codec's.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"
#include "support/orbit_render.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::node;

namespace {

RenderVolume vqFile(const test::TempDir& dir, const codec::Volume& v, const codec::vq::Params& p,
                    const std::string& name, codec::vq::EncodeStats* stats = nullptr) {
  voxwall::Progress quiet;
  codec::writeContainer(codec::vq::encode(v, p, quiet, stats), dir.path(name));
  return RenderVolume::open(dir.path(name));
}

}  // namespace

// Pixels are compared with a tolerance of one level: the two views' samples are bit-identical,
// but with -march=native the compiler may fuse multiply-adds differently in the two raycaster
// instantiations, which moves a colour across a rounding boundary in a handful of pixels.
TEST(VqRender, LosslessRendersLikeRaw) {
  test::TempDir dir;
  // Odd sizes: cells and gradients straddle brick borders and the padded edge.
  for (const codec::Volume& v : {codec::generateSheppLogan(45), codec::generateMarschnerLobb(38)}) {
    const auto raw = RenderVolume::fromVolume(v, 8);
    const auto tf = TransferFunction::preset("ct-soft").rescaled(0, 255);
    for (bool compressed : {true, false}) {
      codec::vq::Params p;
      p.compressedCodebook = compressed;
      const auto vq = vqFile(dir, v, p, "v.vwz");
      EXPECT_EQ(vq.info().codec, codec::vq::VqCodecEntry::kId);
      for (bool shading : {false, true}) {
        const Image reference = test::renderOrbit(raw, 72, 56, tf, shading);
        test::expectImagesNear(
            reference, test::renderOrbit(vq, 72, 56, tf, shading), 1, 70,
            std::string(compressed ? "rbuc" : "plain") + (shading ? " shaded" : ""));
        // Threads and tiles share the per-thread brick cache: still the same pixels.
        test::expectImagesNear(
            reference,
            test::renderOrbit(vq, 72, 56, tf, shading, 3,
                              {{0, 0, 40, 30}, {40, 0, 32, 30}, {0, 30, 72, 26}}),
            1, 70, "tiles");
      }
    }
  }
}

TEST(VqRender, TwoVolumesInOneThreadDoNotShareCachedBricks) {
  // The per-thread cache is keyed per loaded volume: rendering A, then B, then A again on the
  // same threads gives A's pixels both times.
  test::TempDir dir;
  const auto a = vqFile(dir, codec::generateSheppLogan(40), {}, "a.vwz");
  const auto b = vqFile(dir, codec::generateMarschnerLobb(40), {}, "b.vwz");
  const auto tf = TransferFunction::preset("hot").rescaled(0, 255);
  const Image first = test::renderOrbit(a, 48, 48, tf, false, 1);
  const Image other = test::renderOrbit(b, 48, 48, tf, false, 1);
  EXPECT_GT(voxwall::compareImages(first, other).maxAbs, 10);
  test::expectImagesNear(first, test::renderOrbit(a, 48, 48, tf, false, 1), 0);
}

TEST(VqRender, LossyRendersLikeItsDecodedVolumeAndCloseToRaw) {
  test::TempDir dir;
  const codec::Volume v = codec::generateMarschnerLobb(48);
  const auto tf = TransferFunction::preset("cool-warm").rescaled(0, 255);
  const Image reference = test::renderOrbit(RenderVolume::fromVolume(v), 64, 64, tf, true);
  double lastImagePsnr = std::numeric_limits<double>::infinity();
  for (int k : {4, 32, 256}) {
    codec::vq::Params p;
    p.reduction = k;
    codec::vq::EncodeStats stats;
    const auto vq = vqFile(dir, v, p, "lossy.vwz", &stats);
    // The view returns exactly the voxels the codec's decoder (whose PSNR it reports) returns.
    const auto file = codec::ContainerFile::open(dir.path("lossy.vwz"));
    const codec::Volume decoded = codec::vq::decode(file.info(), file.sections());
    EXPECT_DOUBLE_EQ(codec::psnr(v, decoded), stats.psnr);
    const Image image = test::renderOrbit(vq, 64, 64, tf, true);
    test::expectImagesNear(test::renderOrbit(RenderVolume::fromVolume(decoded), 64, 64, tf, true),
                           image, 1, 70, "reduction " + std::to_string(k));
    // Against the raw render: within 4 dB of the volume PSNR the codec reports, and a loss that
    // grows with the reduction.
    const double imagePsnr = voxwall::compareImages(reference, image).psnrDb;
    RecordProperty("image_psnr_reduction_" + std::to_string(k), std::to_string(imagePsnr));
    EXPECT_GT(imagePsnr, stats.psnr - 4.0) << "reduction " << k;
    std::printf("reduction %d: volume PSNR %.2f dB, image PSNR %.2f dB\n", k, stats.psnr,
                imagePsnr);
    EXPECT_LT(imagePsnr, lastImagePsnr + 0.5) << "reduction " << k;
    lastImagePsnr = imagePsnr;
  }
}

class VqViewSamples : public ::testing::TestWithParam<int> {};

TEST_P(VqViewSamples, EqualTheRawViewOfTheDecodedVolumeEverywhere) {
  // Trilinear samples, cached and uncached, inside, on the edges and outside the volume; a
  // lossy codebook gives many distinct codewords, so cells whose bricks share a cache slot occur.
  const codec::Volume v = codec::generateMarschnerLobb(45);
  voxwall::Progress quiet;
  codec::vq::Params p;
  p.reduction = GetParam();
  const auto vc = codec::vq::encode(v, p, quiet);
  const auto rc = codec::rawbricks::encode(codec::vq::decode(vc.info, vc.view()), {8}, quiet);
  const auto rv = codec::rawbricks::Layout(rc.info, rc.view()).view<std::uint8_t>();
  const codec::vq::Layout layout(vc.info, vc.view());
  const auto vv = layout.view();
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> d(-2.f, 47.f);
  codec::kernels::VqView::RayCache cache;
  for (int i = 0; i < 200000; ++i) {
    const float x = d(rng), y = d(rng), z = d(rng);
    ASSERT_EQ(rv.sample(x, y, z), vv.sample(x, y, z, cache)) << x << "," << y << "," << z;
    ASSERT_EQ(rv.sample(x, y, z), vv.sampleNear(x, y, z, cache)) << x << "," << y << "," << z;
    ASSERT_EQ(rv.sample(x, y, z), vv.sample(x, y, z));
  }
}

INSTANTIATE_TEST_SUITE_P(Reductions, VqViewSamples, ::testing::Values(1, 4));
