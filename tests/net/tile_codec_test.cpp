#include <gtest/gtest.h>

#include <voxwall/codec/generators.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/node/renderer.hpp>

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
