// Routing instead of decoding: ranks cut their segments at the display edges the sink's Welcome
// lists (so every segment lies on one display, or on every display of an overlap, or wholly in a
// bezel gap), send bezel-only segments only when the sink asks, and the sink refuses a segment
// whose header disagrees with its rectangle without marking any pixel.
#include <gtest/gtest.h>

#include <voxwall/core/errors.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/frame_pixels.hpp>
#include <voxwall/walls/wall.hpp>

#include "support/rects.hpp"
#include "support/sink_runner.hpp"

using namespace voxwall;

namespace {

net::DisplayCut cutOf(const walls::Wall& wall, bool bezels) {
  net::DisplayCut cut{wall.width, wall.height, {}, bezels};
  for (const auto& d : wall.displays) cut.displays.push_back(d.rect);
  return cut;
}

using test::disjoint;
using test::inside;

// Checks the cut of `rects` (a rank's share, in bands of 1024 rows as ranks render them):
// segments never straddle a display edge, and bezel-only ones appear only when wanted.
void expectRoutable(const walls::Wall& wall, const std::vector<voxwall::Rect>& rects) {
  for (const bool bezels : {false, true}) {
    const auto cut = cutOf(wall, bezels);
    long long displayPixels = 0, area = 0;
    for (const auto& rect : rects)
      for (int y = rect.y; y < rect.y + rect.height; y += 1024) {
        const voxwall::Rect band{rect.x, y, rect.width, std::min(1024, rect.y + rect.height - y)};
        for (const auto& s : net::segmentRects(band, 1024, cut)) {
          area += s.area();
          bool onSome = false;
          for (const auto& d : wall.displays) {
            ASSERT_TRUE(inside(s, d.rect) || disjoint(s, d.rect))
                << wall.id << ": segment " << s.width << "x" << s.height << "+" << s.x << "+" << s.y
                << " straddles display " << d.name;
            onSome = onSome || inside(s, d.rect);
          }
          if (!bezels) {
            ASSERT_TRUE(onSome) << wall.id << ": a bezel-only segment was sent";
          }
          if (onSome) displayPixels += s.area();
        }
      }
    if (bezels) {
      long long total = 0;
      for (const auto& r : rects) total += r.area();
      EXPECT_EQ(area, total) << wall.id;
    }
    // Displays are covered (overlapping displays' shared pixels once: segments do not overlap).
    if (!wall.overlapping) {
      EXPECT_EQ(displayPixels, wall.displayPixels()) << wall.id;
    }
  }
}

}  // namespace

TEST(Routing, BigeyeSegmentsNeverStraddleADisplayEdge) {
  const auto wall = walls::loadWall(VOXWALL_WALLS_DIR "/bigeye.json");
  // Three strips (the static cut of three ranks) and an uneven grid like the balancer's.
  const int w = wall.width, h = wall.height;
  expectRoutable(wall, {{0, 0, w, 1446}, {0, 1446, w, 1446}, {0, 2892, w, h - 2892}});
  expectRoutable(wall, {{0, 0, 2500, 3000}, {2500, 0, w - 2500, 3000}, {0, 3000, w, h - 3000}});
}

TEST(Routing, TideSurfacesWithDisplaysPerScreenAndOverlapsAreCutAtEveryEdge) {
  const auto tide = walls::loadWall(VOXWALL_WALLS_DIR "/tide-reference.json");
  ASSERT_EQ(tide.displays.size(), 12u);
  expectRoutable(tide, {{0, 0, tide.width, tide.height}});
  const auto blend = walls::parseWall(R"({"surfaces": [{"displayWidth": 1280, "displayHeight": 800,
      "screenCountX": 3, "screenCountY": 2, "bezelWidth": -64, "bezelHeight": -32}]})",
                                      "blend.json");
  ASSERT_TRUE(blend.overlapping);
  expectRoutable(blend, {{0, 0, blend.width, blend.height / 2},
                         {0, blend.height / 2, blend.width, blend.height - blend.height / 2}});
}

TEST(Routing, TheSinksWelcomeSaysWhereToCutAndWhetherBezelsAreWanted) {
  for (const bool mosaic : {false, true}) {
    auto settings = test::twoDisplaySink();
    settings.mosaic = mosaic;
    test::SinkRunner sink(settings);
    net::TileStreamer streamer("127.0.0.1", sink.port(),
                               net::Hello{net::Role::Renderer, 0, 1, "t2x1", ""});
    ASSERT_TRUE(streamer.beginFrame(0));
    const auto& cut = streamer.displayCut();
    ASSERT_EQ(cut.displays.size(), 2u);
    EXPECT_EQ(cut.displays[1], (voxwall::Rect{24, 0, 20, 10}));
    EXPECT_EQ(cut.bezels, mosaic);
    // What the rank sends of the whole screen: the gap only for a mosaic.
    voxwall::Image screen(44, 10);
    for (auto& p : screen.pixels) p = 0xff808080u;
    const auto tiles = net::encodeTiles(screen, {0, 0, 44, 10}, {0, 0, 0}, {}, cut);
    EXPECT_EQ(tiles.size(), mosaic ? 3u : 2u);
    ASSERT_TRUE(streamer.sendTiles(tiles, 0));
    ASSERT_TRUE(streamer.endFrame());
    EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 1; }))
        << sink.log();
  }
}

TEST(Routing, ASegmentWhoseHeaderDisagreesWithItsRectangleIsRefusedAndMarksNothing) {
  const auto wall = test::twoDisplayWall();
  std::vector<walls::FrameEvent> events;
  walls::FrameAssembler assembler(wall, {},
                                  [&](const walls::FrameEvent& e) { events.push_back(e); });
  voxwall::Image left(20, 10), right(20, 10);
  const auto l = net::encodeTiles(left, {0, 0, 20, 10}, {0, 0, 0}, {})[0];
  const auto r = net::encodeTiles(right, {24, 0, 20, 10}, {0, 0, 0}, {})[0];
  EXPECT_FALSE(assembler.addTile(0, {l.rect, l.codec, 0, l.bytes}, 0, "rank 0"));
  // The right display's JPEG, labelled as a 22-pixel-wide segment.
  try {
    assembler.addTile(0, {{22, 0, 22, 10}, r.codec, 0, r.bytes}, 1, "rank 1");
    FAIL() << "a JPEG of 20x10 passed as 22x10";
  } catch (const FormatError& e) {
    EXPECT_STREQ(e.what(), "rank 1: JPEG tile is 20x10, the message says 22x10");
  }
  // Nothing of it was marked: the frame still needs the right display.
  EXPECT_EQ(assembler.openFrames(), 1u);
  const auto done = assembler.addTile(0, {r.rect, r.codec, 0, r.bytes}, 1, "rank 1");
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->segments.size(), 2u);
  EXPECT_TRUE(events.empty());

  // Through the sink: the peer is dropped with one line naming the disagreement, no frame shown.
  test::SinkRunner sink(test::twoDisplaySink());
  auto c = net::Connection::open("127.0.0.1", sink.port(),
                                 net::Hello{net::Role::Renderer, 0, 1, "t2x1", ""}, 2000);
  c->send(net::encodeMessage(0, net::TileMessage{l.rect, l.codec, 0, l.bytes}));
  c->send(net::encodeMessage(0, net::TileMessage{{22, 0, 22, 10}, r.codec, 0, r.bytes}));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.peersDropped == 1; }))
      << sink.log();
  EXPECT_NE(sink.log().find("JPEG tile is 20x10, the message says 22x10"), std::string::npos)
      << sink.log();
  EXPECT_EQ(sink.sink().stats().framesPresented, 0);
}

TEST(Routing, PixelsAreDecodedOnlyForWhatNeedsThemAndMatchWhatWasSent) {
  const auto wall = test::twoDisplayWall();
  walls::FrameAssembler assembler(wall, {}, {});
  voxwall::Image screen(44, 10);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 44; ++x) screen.at(x, y) = 0xff000000u | std::uint32_t(x * 5 + y * 1000);
  net::TileCodecSettings s;
  s.codec = net::TileCodec::Raw;
  s.segmentPixels = 8;
  const auto tiles = net::encodeTiles(screen, {0, 0, 44, 10}, {0, 0, 0}, s, cutOf(wall, true));
  std::optional<walls::AssembledFrame> done;
  for (const auto& t : tiles) done = assembler.addTile(0, {t.rect, t.codec, 0, t.bytes}, 0, "r");
  ASSERT_TRUE(done.has_value());
  // One display exactly as sent; the whole screen at half size takes the centre of each block.
  const auto right = walls::decodeRegion(*done, wall.displays[1].rect, 1, 0);
  EXPECT_EQ(right.pixels, screen.crop(wall.displays[1].rect).pixels);
  const auto half = walls::decodeRegion(*done, {0, 0, 44, 10}, 2, 0);
  ASSERT_EQ(half.width, 22);
  ASSERT_EQ(half.height, 5);
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 22; ++x) EXPECT_EQ(half.at(x, y), screen.at(2 * x + 1, 2 * y + 1));
}
