// A rank's renderer (node/rank_renderer.hpp): rectangles whole or in bands give the same pixels,
// parts are handed on as they finish, a frame given up renders nothing more, and memory is read
// without rendering.
#include <gtest/gtest.h>

#include <voxwall/codec/generators.hpp>
#include <voxwall/node/rank_renderer.hpp>

#include "support/image_expect.hpp"

using namespace voxwall;
using namespace voxwall::node;

namespace {

struct Fixture {
  RenderVolume volume = RenderVolume::fromVolume(codec::generateSheppLogan(40), 8);
  TransferFunction tf = TransferFunction::preset("ct-soft").rescaled(0, 255);
  RenderSettings settings;
  std::unique_ptr<Backend> backend = makeCpuBackend(2);

  RankFrame frame(std::vector<Rect> rects, bool keepPixels) const {
    RankFrame f;
    f.volume = &volume, f.tf = &tf;
    f.camera = orbitCamera(Orbit{}, boundingRadius(volume.info()));
    f.screenWidth = 96, f.screenHeight = 72;
    f.cellPixels = 16;
    f.rects = std::move(rects);
    f.keepPixels = keepPixels;
    f.bandRows = 7;
    return f;
  }
};

}  // namespace

TEST(RankRenderer, BandsHandedOnGiveTheWholeRectanglesPixels) {
  Fixture fx;
  RankRenderer renderer(*fx.backend, fx.settings);
  const std::vector<Rect> rects = {{0, 0, 50, 72}, {50, 10, 46, 30}};
  const RankFrameResult whole = renderer.render(fx.frame(rects, true));
  ASSERT_EQ(whole.tiles.size(), 2u);
  EXPECT_FALSE(whole.abandoned);
  EXPECT_GT(whole.samples, 0u);
  EXPECT_EQ(whole.rays, std::uint64_t(50 * 72 + 46 * 30));
  EXPECT_EQ(whole.latticeStride, 1);
  EXPECT_GT(whole.costs.total(), 0.0);

  RankFrame banded = fx.frame(rects, false);
  std::vector<Image> pasted = {Image(50, 72), Image(46, 30)};
  int parts = 0;
  banded.onPart = [&](const Rect& part, const Image& pixels, double renderSeconds) {
    EXPECT_LE(part.height, 7);
    EXPECT_GE(renderSeconds, 0.0);
    const std::size_t t = part.x < 50 ? 0 : 1;
    pasted[t].paste(pixels, {part.x - rects[t].x, part.y - rects[t].y, part.width, part.height});
    ++parts;
    return true;
  };
  const RankFrameResult bands = renderer.render(banded);
  EXPECT_EQ(parts, (72 + 6) / 7 + (30 + 6) / 7);
  ASSERT_EQ(bands.tiles.size(), 2u);
  EXPECT_TRUE(bands.tiles[0].image.pixels.empty());  // no pixels kept
  EXPECT_EQ(bands.samples, whole.samples);
  for (std::size_t t = 0; t < 2; ++t)
    test::expectImagesNear(whole.tiles[t].image, pasted[t], 0, 0, "band-by-band tile");
}

TEST(RankRenderer, APartHandlerThatFailsIsNotCalledAgainButTheFrameIsRendered) {
  Fixture fx;
  RankRenderer renderer(*fx.backend, fx.settings);
  RankFrame f = fx.frame({{0, 0, 96, 72}}, false);
  int calls = 0;
  f.onPart = [&](const Rect&, const Image&, double) {
    ++calls;
    return false;
  };
  const RankFrameResult r = renderer.render(f);
  EXPECT_EQ(calls, 1);
  EXPECT_FALSE(r.abandoned);
  EXPECT_EQ(r.rays, std::uint64_t(96 * 72));
}

TEST(RankRenderer, AFrameGivenUpBeforeItStartsRendersNothing) {
  Fixture fx;
  RankRenderer renderer(*fx.backend, fx.settings);
  RankFrame f = fx.frame({{0, 0, 96, 72}, {0, 0, 10, 10}}, false);
  int parts = 0;
  f.onPart = [&](const Rect&, const Image&, double) { return ++parts, true; };
  f.abandoned = [] { return true; };
  const RankFrameResult r = renderer.render(f);
  EXPECT_TRUE(r.abandoned);
  EXPECT_EQ(parts, 0);
  EXPECT_EQ(r.samples, 0u);
  // The next frame, not abandoned, renders whole.
  f.abandoned = [] { return false; };
  const RankFrameResult next = renderer.render(f);
  EXPECT_FALSE(next.abandoned);
  EXPECT_EQ(next.rays, std::uint64_t(96 * 72 + 100));
}

TEST(RankRenderer, NoRectanglesRenderNothingAndMemoryIsReadWithoutRendering) {
  Fixture fx;
  RankRenderer renderer(*fx.backend, fx.settings);
  const RankFrameResult r = renderer.render(fx.frame({}, true));
  EXPECT_TRUE(r.tiles.empty());
  EXPECT_EQ(r.samples, 0u);
  EXPECT_EQ(r.latticeStride, 0);
  EXPECT_GT(renderer.memory().residentBytes, 0u);
}

TEST(RowBands, CutARectangleTopToBottom) {
  const Rect r{3, 5, 10, 16};
  EXPECT_EQ(rowBands(r, 100), std::vector<Rect>{r});
  const auto bands = rowBands(r, 6);
  ASSERT_EQ(bands.size(), 3u);
  EXPECT_EQ(bands[2], (Rect{3, 17, 10, 4}));
  EXPECT_EQ(rowBands(r, 0).size(), 16u);  // at least a row a band
}

// A probe renders the screen at 1/step a side and predicts the full screen's samples by step^2:
// the same view on a screen twice as wide and high is predicted at about four times the samples.
TEST(RankRenderer, AProbePredictsMoreForABiggerScreen) {
  Fixture fx;
  fx.settings.latticeStride = 1;
  RankRenderer renderer(*fx.backend, fx.settings);
  RankFrame small = fx.frame({}, true);
  small.screenWidth = 384, small.screenHeight = 288;
  RankFrame big = small;
  big.screenWidth = 768, big.screenHeight = 576;
  const FrameProbe a = renderer.probe(small, 8), b = renderer.probe(big, 8);
  EXPECT_GT(a.samples, 0u);
  EXPECT_GE(a.seconds, 0.0);
  EXPECT_GT(double(b.samples), 3.0 * double(a.samples));
  EXPECT_LT(double(b.samples), 5.0 * double(a.samples));
  EXPECT_THROW(renderer.probe(small, 0), std::invalid_argument);
}
