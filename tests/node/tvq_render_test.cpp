// Rendering the tvq codec's view (associated codebooks) against its decoded volume, at every
// progressive level.
#include <gtest/gtest.h>

#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"
#include "support/orbit_render.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::node;

// The view rounds integer data as the decoder does, so the view and the decoded volume hold the
// same values: the images agree to a rounding step.
TEST(TvqRender, EveryProgressiveLevelRendersLikeItsDecodedVolume) {
  test::TempDir dir;
  const auto tf = TransferFunction::preset("ct-soft").rescaled(0, 255);
  for (auto transform : {codec::tvq::Transform::Klt, codec::tvq::Transform::Dct}) {
    const codec::Volume v = codec::generateSheppLogan(40);
    codec::tvq::Params p;
    p.transform = transform, p.codeBits = 12, p.iterations = 3, p.subvolumeVoxels = 24;
    voxwall::Progress quiet;
    const std::string path = dir.path("sl.vwz");
    codec::writeContainer(codec::tvq::encode(v, p, quiet), path);
    const auto container = codec::ContainerFile::open(path);
    const codec::tvq::Layout layout(container.info(), container.sections());
    const char* levels[] = {"dc", "lp", "bp", "all"};
    for (int l = 0; l < codec::tvq::kProgressiveLevels; ++l) {
      codec::CodecOptionValues options;
      options.set("--progressive", levels[l]);
      const auto file = RenderVolume::open(path, std::nullopt, options);
      const auto reference = RenderVolume::fromVolume(layout.decode(l));
      for (bool shading : {false, true}) {
        const std::string label = std::string(levels[l]) + (shading ? " shaded" : "") +
                                  (transform == codec::tvq::Transform::Klt ? " KLT" : " DCT");
        test::expectImagesNear(test::renderOrbit(reference, 48, 40, tf, shading),
                               test::renderOrbit(file, 48, 40, tf, shading), 1, 70, label);
      }
    }
    // The levels are different pictures: dc alone is not the full volume.
    codec::CodecOptionValues dc;
    dc.set("--progressive", "dc");
    const Image coarse =
        test::renderOrbit(RenderVolume::open(path, std::nullopt, dc), 48, 40, tf, false);
    const Image full = test::renderOrbit(RenderVolume::open(path), 48, 40, tf, false);
    EXPECT_LT(voxwall::compareImages(full, coarse).psnrDb, 60.0);
  }
}

TEST(TvqRender, ProgressiveIsRefusedForAnotherCodecsFile) {
  test::TempDir dir;
  voxwall::Progress quiet;
  codec::writeContainer(codec::rawbricks::encode(codec::generateMenger(2), {}, quiet),
                        dir.path("r.vwz"));
  codec::CodecOptionValues options;
  options.set("--progressive", "dc");
  EXPECT_THROW(RenderVolume::open(dir.path("r.vwz"), std::nullopt, options), std::invalid_argument);
  options.set("--progressive", "half");
  codec::tvq::Params p;
  p.codeBits = 6, p.iterations = 1;
  codec::writeContainer(codec::tvq::encode(codec::generateMenger(2), p, quiet), dir.path("t.vwz"));
  EXPECT_THROW(RenderVolume::open(dir.path("t.vwz"), std::nullopt, options), std::invalid_argument);
}
