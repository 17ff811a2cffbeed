#include <gtest/gtest.h>

#include <voxwall/codec/generators.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/net/wire.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/rects.hpp"

using namespace voxwall;

namespace {

// A real rendered tile: what the ranks compress.
voxwall::Image renderedImage(int w, int h) {
  const auto volume = node::RenderVolume::fromVolume(codec::generateSheppLogan(48), 8);
  const auto tf = node::TransferFunction::preset("mri").rescaled(0, 255);
  node::Orbit orbit;
  const auto camera = node::orbitCamera(orbit, node::boundingRadius(volume.info()));
  node::RenderSettings settings;
  settings.shading = true;
  const auto plan = node::planFrame(volume, camera, w, h, tf, settings);
  voxwall::Image image;
  node::makeCpuBackend(2)->render(volume, plan, {0, 0, w, h}, image);
  return image;
}

// The premultiplied image over an opaque background, as the sink should show it.
voxwall::Image overBlack(const voxwall::Image& im) {
  voxwall::Image out = im;
  for (auto& p : out.pixels) p |= 0xff000000u;
  return out;
}

voxwall::Image decodeAll(const std::vector<net::EncodedTile>& tiles, int w, int h, int x0, int y0) {
  voxwall::Image out(w, h);
  for (const auto& t : tiles) {
    const auto part = net::decodeTile(t.bytes, t.codec, t.rect.width, t.rect.height, "test");
    out.paste(part, {t.rect.x - x0, t.rect.y - y0, t.rect.width, t.rect.height});
  }
  return out;
}

}  // namespace

TEST(TileCodec, LosslessCodecsAreExactAndSegmentsCoverTheTile) {
  const auto image = renderedImage(150, 90);
  for (auto codec : {net::TileCodec::Raw, net::TileCodec::Deflate}) {
    net::TileCodecSettings s;
    s.codec = codec;
    s.segmentPixels = 64;  // 3 x 2 segments, the last ones partial
    const auto tiles = net::encodeTiles(image, {100, 50, 150, 90}, {0, 0, 0}, s);
    ASSERT_EQ(tiles.size(), 6u);
    long long area = 0;
    for (const auto& t : tiles) area += t.rect.area();
    EXPECT_EQ(area, 150 * 90);
    EXPECT_EQ(decodeAll(tiles, 150, 90, 100, 50).pixels, overBlack(image).pixels)
        << net::tileCodecName(codec);
  }
}

TEST(TileCodec, JpegAtTheDefaultsKeeps40Decibels) {
  const auto image = renderedImage(320, 240);
  const auto reference = overBlack(image);
  for (auto sub : {net::Subsampling::S444, net::Subsampling::S422, net::Subsampling::S420}) {
    net::TileCodecSettings s;
    s.subsampling = sub;
    const auto tiles = net::encodeTiles(image, {0, 0, 320, 240}, {0, 0, 0}, s);
    const auto decoded = decodeAll(tiles, 320, 240, 0, 0);
    const auto diff = voxwall::compareImages(decoded, reference);
    EXPECT_GE(diff.psnrDb, 40.0) << "subsampling " << int(sub);
    std::size_t bytes = 0;
    for (const auto& t : tiles) bytes += t.bytes.size();
    EXPECT_LT(bytes, std::size_t(320 * 240 * 3 / 4));  // compresses at least 4:1
  }
}

TEST(TileCodec, CompositesOntoTheBackground) {
  voxwall::Image clear(8, 8);  // fully transparent
  net::TileCodecSettings s;
  s.codec = net::TileCodec::Raw;
  const auto tiles = net::encodeTiles(clear, {0, 0, 8, 8}, {1.0, 0.5, 0.0}, s);
  const auto out = net::decodeTile(tiles[0].bytes, tiles[0].codec, 8, 8, "t");
  EXPECT_EQ(out.pixels[0], 0xff0080ffu);  // opaque, R 255, G 128, B 0
}

TEST(TileCodec, CorruptOrMismatchedTilesAreRefused) {
  const auto image = renderedImage(64, 48);
  net::TileCodecSettings s;
  const auto jpeg = net::encodeTiles(image, {0, 0, 64, 48}, {0, 0, 0}, s)[0].bytes;
  EXPECT_THROW(net::decodeTile(jpeg, net::TileCodec::Jpeg, 64, 40, "t"), FormatError);
  auto truncated = jpeg;
  truncated.resize(jpeg.size() / 2);
  EXPECT_THROW(net::decodeTile(truncated, net::TileCodec::Jpeg, 64, 48, "t"), FormatError);
  std::vector<std::byte> garbage(500, std::byte{0x5a});
  EXPECT_THROW(net::decodeTile(garbage, net::TileCodec::Jpeg, 64, 48, "t"), FormatError);
  EXPECT_THROW(net::decodeTile(garbage, net::TileCodec::Deflate, 64, 48, "t"), FormatError);
  EXPECT_THROW(net::decodeTile(garbage, net::TileCodec::Raw, 64, 48, "t"), FormatError);
  EXPECT_THROW(net::decodeTile(garbage, net::TileCodec::Raw, 0, 48, "t"), FormatError);
}

namespace {

using test::disjoint;
using test::inside;

// Two 100x60 displays side by side with a 6-pixel gap, a 206x60 screen.
net::DisplayCut twoDisplays(bool bezels) {
  return {206, 60, {{0, 0, 100, 60}, {106, 0, 100, 60}}, bezels};
}

}  // namespace

TEST(TileCodec, SegmentsAreCutAtDisplayEdgesAndTileTheRectangle) {
  const voxwall::Rect rect{50, 10, 156, 50};
  const auto parts = net::segmentRects(rect, 32, twoDisplays(true));
  long long area = 0;
  for (const auto& p : parts) {
    area += p.area();
    EXPECT_LE(p.width, 32);
    EXPECT_LE(p.height, 32);
    EXPECT_TRUE(inside(p, rect));
    for (const auto& d : twoDisplays(true).displays)
      EXPECT_TRUE(inside(p, d) || disjoint(p, d))
          << p.width << "x" << p.height << "+" << p.x << "+" << p.y;
  }
  EXPECT_EQ(area, rect.area());  // with bezels wanted, nothing is left out
}

TEST(TileCodec, BezelOnlySegmentsAreLeftOutUnlessWanted) {
  const voxwall::Rect rect{0, 0, 206, 60};
  const auto all = net::segmentRects(rect, 1024, twoDisplays(true));
  const auto some = net::segmentRects(rect, 1024, twoDisplays(false));
  ASSERT_EQ(all.size(), 3u);  // left display, the gap, right display
  ASSERT_EQ(some.size(), 2u);
  EXPECT_EQ(some[0], (voxwall::Rect{0, 0, 100, 60}));
  EXPECT_EQ(some[1], (voxwall::Rect{106, 0, 100, 60}));
  // No displays known (an empty Welcome): one segment per 1024 pixels, as before.
  EXPECT_EQ(net::segmentRects(rect, 1024).size(), 1u);
}

TEST(TileCodec, ReducedFramesAreCutAtTheReducedEdgesAndCoverEveryDisplayPixel) {
  const auto cut = twoDisplays(false);
  for (int step : {2, 3, 4, 16}) {
    const int w = net::reducedSide(206, step), h = net::reducedSide(60, step);
    const auto parts = net::segmentRects({0, 0, w, h}, 1024, cut, step);
    // Every display pixel is in some segment's virtual-screen rectangle.
    std::vector<int> covered(206 * 60, 0);
    for (const auto& p : parts) {
      const auto r = net::fullScreenRect(p, step, 206, 60);
      for (int y = r.y; y < r.y + r.height; ++y)
        for (int x = r.x; x < r.x + r.width; ++x) covered[std::size_t(y * 206 + x)] = 1;
    }
    for (const auto& d : cut.displays)
      for (int y = d.y; y < d.y + d.height; ++y)
        for (int x = d.x; x < d.x + d.width; ++x)
          ASSERT_TRUE(covered[std::size_t(y * 206 + x)]) << "step " << step << " " << x << "," << y;
  }
}

TEST(TileCodec, TheSinksCheapCheckFindsWhatDisagreesWithTheRectangle) {
  const auto image = renderedImage(64, 48);
  for (auto codec : {net::TileCodec::Jpeg, net::TileCodec::Raw, net::TileCodec::Deflate}) {
    net::TileCodecSettings s;
    s.codec = codec;
    const auto bytes = net::encodeTiles(image, {0, 0, 64, 48}, {0, 0, 0}, s)[0].bytes;
    const char* name = net::tileCodecName(codec);
    EXPECT_NO_THROW(net::checkTile(bytes, codec, 64, 48, "t")) << name;
    EXPECT_THROW(net::checkTile(bytes, codec, 64, 40, "t"), FormatError) << name;
    auto cut = bytes;
    cut.resize(bytes.size() / 2);
    auto longer = bytes;
    longer.push_back(std::byte{0});
    if (codec == net::TileCodec::Jpeg) {  // raw bytes cannot tell 48x64 from 64x48; a header can
      EXPECT_THROW(net::checkTile(bytes, codec, 48, 64, "t"), FormatError) << name;
    }
    if (codec != net::TileCodec::Jpeg) {  // a JPEG's header survives a cut or longer body
      EXPECT_THROW(net::checkTile(cut, codec, 64, 48, "t"), FormatError) << name;
      EXPECT_THROW(net::checkTile(longer, codec, 64, 48, "t"), FormatError) << name;
    }
  }
  try {
    const auto jpeg = net::encodeTiles(image, {0, 0, 64, 48}, {0, 0, 0}, {})[0].bytes;
    net::checkTile(jpeg, net::TileCodec::Jpeg, 64, 40, "rank 1");
    FAIL() << "a JPEG of another size passed";
  } catch (const FormatError& e) {
    EXPECT_STREQ(e.what(), "rank 1: JPEG tile is 64x48, the message says 64x40");
  }
}

TEST(TileCodec, JpegTilesDecodeScaledDownInTheDecoder) {
  voxwall::Image flat(100, 60);
  for (auto& p : flat.pixels) p = 0xff3070b0u;
  const auto jpeg = net::encodeTiles(flat, {0, 0, 100, 60}, {0, 0, 0}, {})[0].bytes;
  for (int d : {1, 2, 4, 8}) {
    const auto small = net::decodeTileScaled(jpeg, net::TileCodec::Jpeg, 100, 60, d, "t");
    EXPECT_EQ(small.width, (100 + d - 1) / d);
    EXPECT_EQ(small.height, (60 + d - 1) / d);
    const std::uint32_t p = small.at(small.width / 2, small.height / 2);
    EXPECT_NEAR(int(p & 255), 0xb0, 3);
    EXPECT_NEAR(int((p >> 16) & 255), 0x30, 3);
  }
  EXPECT_THROW(net::decodeTileScaled(jpeg, net::TileCodec::Jpeg, 100, 60, 3, "t"),
               std::invalid_argument);
  EXPECT_THROW(net::decodeTileScaled(jpeg, net::TileCodec::Raw, 100, 60, 2, "t"),
               std::invalid_argument);
}
