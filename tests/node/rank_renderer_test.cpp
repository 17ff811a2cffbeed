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

namespace {

// A vq volume of several pages (its pages are decoded by the packets), an orbit's frames over the
// whole screen, and renderers on backends of `budget` bytes of pages.
struct AheadFixture {
  RenderVolume volume = [] {
    voxwall::Progress quiet;
    std::string report;
    return RenderVolume::fromCompressed(
        codec::codecNamed("vq").encode(codec::generateSheppLogan(160), {}, quiet, report));
  }();
  // Nearly opaque: the rays stop at the surface they meet, so each side of the volume needs pages
  // of its own.
  TransferFunction tf = TransferFunction::preset("grey").rescaled(0, 255);
  RenderSettings settings;

  RankFrame frame(double azimuth) const {
    RankFrame f;
    f.volume = &volume, f.tf = &tf;
    Orbit orbit;
    orbit.azimuthDeg = azimuth;
    orbit.distance = 1.3;
    f.camera = orbitCamera(orbit, boundingRadius(volume.info()));
    f.screenWidth = 160, f.screenHeight = 120;
    f.rects = {{0, 0, 160, 120}};
    return f;
  }
};

}  // namespace

// Decoding the next frame's pages while the rank waits gives the same pictures, byte for byte, as
// decoding them on the rays. A pass at full resolution leaves the rays of every later frame of the
// orbit no page to decode; the default pass, at half resolution a side, nearly none (rays a
// quarter as dense miss the odd page that only a sliver of the screen reaches: 1 of 31 here).
TEST(RankRenderer, DecodingAheadGivesTheSamePicturesAndLeavesTheRaysNoPageToDecode) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "no SIMD packets on this CPU: no decoded pages";
  const AheadFixture fx;
  const auto full = makeCpuBackend(2), half = makeCpuBackend(2), onRays = makeCpuBackend(2);
  RankRenderer fullAhead(*full, fx.settings), halfAhead(*half, fx.settings);
  RankRenderer without(*onRays, fx.settings);
  std::uint64_t needed = 0, fullDecoded = 0, fullAheadPages = 0, halfDecoded = 0;
  for (int k = 0; k < 4; ++k) {
    const RankFrame frame = fx.frame(30.0 + 60.0 * k);
    const RankFrameResult a = fullAhead.render(frame), h = halfAhead.render(frame);
    const RankFrameResult b = without.render(frame);
    ASSERT_EQ(a.tiles.size(), 1u);
    EXPECT_EQ(a.tiles[0].image.pixels, b.tiles[0].image.pixels) << "frame " << k;
    EXPECT_EQ(h.tiles[0].image.pixels, b.tiles[0].image.pixels) << "frame " << k;
    EXPECT_GT(a.pages.hits, 0u);
    EXPECT_EQ(a.pages.evictions + h.pages.evictions, 0u);
    if (k == 0) {
      EXPECT_GT(a.pages.decoded, 0u);
      EXPECT_EQ(a.pages.ahead + h.pages.ahead, 0u);
    } else {
      needed += b.pages.decoded;
      fullDecoded += a.pages.decoded, fullAheadPages += a.pages.ahead;
      halfDecoded += h.pages.decoded;
    }
    const RankFrame next = fx.frame(30.0 + 60.0 * (k + 1));
    fullAhead.decodeAhead(next, 1);
    halfAhead.decodeAhead(next);
    fullAhead.finishAhead();
    halfAhead.finishAhead();
  }
  EXPECT_GT(needed, 10u);  // the later frames do need pages of their own
  EXPECT_EQ(fullDecoded, 0u) << "pages the full-resolution pass ahead missed";
  EXPECT_EQ(fullAheadPages, needed);
  EXPECT_LE(halfDecoded * 10, needed) << "the half-resolution pass missed over a tenth";
}

// A path that stays where it is needs no new page: nothing is decoded ahead.
TEST(RankRenderer, AStillPathDecodesNothingAhead) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "no SIMD packets on this CPU: no decoded pages";
  const AheadFixture fx;
  const auto backend = makeCpuBackend(2);
  RankRenderer renderer(*backend, fx.settings);
  const RankFrame frame = fx.frame(40);
  EXPECT_GT(renderer.render(frame).pages.decoded, 0u);
  renderer.decodeAhead(frame);
  renderer.finishAhead();
  const RankFrameResult again = renderer.render(frame);
  EXPECT_EQ(again.pages.ahead, 0u);
  EXPECT_EQ(again.pages.decoded, 0u);
}

// A budget that holds a frame's pages and little more: decoding ahead fills the free slots and
// evicts none of the pages the rank holds (the pages it finds no slot for are decoded for its
// rays only, and not counted as decoded ahead); after a frame that had to evict, nothing is
// decoded ahead at all.
TEST(RankRenderer, DecodingAheadNeverEvictsAndStaysOutOfABudgetTooSmall) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "no SIMD packets on this CPU: no decoded pages";
  const AheadFixture fx;
  const std::uint64_t page = std::uint64_t(PageCache::kVoxels);  // a uint8 page's bytes
  std::uint64_t firstPages = 0;
  {
    const auto probe = makeCpuBackend(2);
    RankRenderer renderer(*probe, fx.settings);
    firstPages = renderer.render(fx.frame(30)).pages.decoded;
    ASSERT_GT(firstPages, 2u);
  }
  // Room for the first frame's pages and two more.
  const auto tight = makeCpuBackend(2, true, (firstPages + 2) * page);
  RankRenderer renderer(*tight, fx.settings);
  const RankFrameResult first = renderer.render(fx.frame(30));
  ASSERT_EQ(first.pages.evictions, 0u);
  renderer.decodeAhead(fx.frame(120));
  renderer.finishAhead();
  const DecodeCacheUse use = cpuDecodeCacheUse(*tight);
  EXPECT_EQ(use.evictions, 0u) << "decoding ahead evicted a page";
  EXPECT_EQ(use.misses, firstPages + 2) << "the two free slots are filled ahead";
  // The next frame needs more than the budget: it evicts, and then nothing is decoded ahead.
  const RankFrameResult second = renderer.render(fx.frame(120));
  EXPECT_EQ(second.pages.ahead, 2u);
  EXPECT_GT(second.pages.evictions, 0u);
  renderer.decodeAhead(fx.frame(210));
  renderer.finishAhead();
  EXPECT_EQ(renderer.render(fx.frame(210)).pages.ahead, 0u);
}

// Rectangles that tile a screen still tile it at 1/step a side (ceil), edge by edge; one narrower
// than a step may vanish, and step 1 keeps them as they are.
TEST(RankRenderer, ReducedRectanglesStillTileTheReducedScreen) {
  const std::vector<Rect> cut = {{0, 0, 50, 61}, {50, 0, 1, 61}, {51, 0, 48, 30}, {51, 30, 48, 31}};
  EXPECT_EQ(reducedRects(cut, 99, 61, 1), cut);
  const auto reduced = reducedRects(cut, 99, 61, 4);  // a 25 x 16 screen
  long long area = 0;
  for (const Rect& r : reduced) {
    EXPECT_GE(r.x, 0);
    EXPECT_LE(r.x + r.width, 25);
    EXPECT_LE(r.y + r.height, 16);
    area += r.area();
  }
  EXPECT_EQ(area, 25 * 16);       // no gap, no overlap (they are disjoint by construction of edges)
  ASSERT_EQ(reduced.size(), 3u);  // the 1-pixel strip at x 50 vanished
  EXPECT_EQ(reduced[0], (Rect{0, 0, 12, 16}));
  EXPECT_EQ(reduced[1], (Rect{12, 0, 13, 7}));
  EXPECT_EQ(reduced[2], (Rect{12, 7, 13, 9}));
}
