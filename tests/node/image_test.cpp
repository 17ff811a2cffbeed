#include <gtest/gtest.h>

#include <voxwall/core/errors.hpp>
#include <voxwall/core/image.hpp>

#include "support/temp_dir.hpp"

using namespace voxwall;

namespace {
std::uint32_t rgba(int r, int g, int b, int a) {
  return std::uint32_t(r) | std::uint32_t(g) << 8 | std::uint32_t(b) << 16 | std::uint32_t(a) << 24;
}
}  // namespace

TEST(Image, PngRoundTripKeepsOpaquePixelsAndStraightensAlpha) {
  test::TempDir dir;
  Image img(3, 2);
  img.at(0, 0) = rgba(255, 0, 0, 255);
  img.at(1, 0) = rgba(10, 20, 30, 255);
  img.at(2, 1) = rgba(50, 25, 0, 128);  // premultiplied: straight colour ~ (100, 50, 0)
  writeImage(img, dir.path("a.png"));
  const Image back = readImage(dir.path("a.png"));
  EXPECT_EQ(back.at(0, 0), img.at(0, 0));
  EXPECT_EQ(back.at(1, 0), img.at(1, 0));
  EXPECT_EQ(back.at(0, 1), 0u);
  EXPECT_LE(compareImages(img, back).maxAbs, 1);
}

TEST(Image, BackgroundMakesItOpaque) {
  test::TempDir dir;
  Image img(1, 1);
  img.at(0, 0) = rgba(100, 0, 0, 128);
  writeImage(img, dir.path("b.png"), glm::dvec3(0, 0, 1));
  const Image back = readImage(dir.path("b.png"));
  EXPECT_EQ(back.at(0, 0) >> 24, 255u);
  EXPECT_NEAR(double((back.at(0, 0) >> 16) & 255), 127.0, 1.0);  // blue through 1 - 128/255
}

TEST(Image, ExrIsWritable) {
  test::TempDir dir;
  Image img(4, 4);
  img.at(1, 1) = rgba(255, 255, 255, 255);
  writeImage(img, dir.path("c.exr"));
  EXPECT_LE(compareImages(img, readImage(dir.path("c.exr"))).maxAbs, 1);
}

TEST(Image, UnwritablePathGivesAFormatError) {
  Image img(2, 2);
  EXPECT_THROW(writeImage(img, "/nonexistent-dir/x.png"), FormatError);
}

TEST(Image, CropAndPasteAreInverse) {
  Image img(5, 4);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = std::uint32_t(i);
  const Rect r{1, 2, 3, 2};
  const Image c = img.crop(r);
  EXPECT_EQ(c.at(0, 0), img.at(1, 2));
  Image blank(5, 4);
  blank.paste(c, r);
  EXPECT_EQ(blank.at(3, 3), img.at(3, 3));
  EXPECT_EQ(blank.at(0, 0), 0u);
  EXPECT_THROW(img.crop({4, 0, 2, 1}), std::invalid_argument);
}
