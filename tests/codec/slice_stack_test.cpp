// Slice stacks (directories of images, multi-page TIFF) read through core's image-file module,
// written here with OpenImageIO itself: a test program of its own, since linking OpenImageIO
// costs every process of a program about 0.3 s at start.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <voxwall/codec/volume_io.hpp>

#include "support/format_error_expect.hpp"
#include "support/patterned_volume.hpp"
#include "support/temp_dir.hpp"
#include "support/volume_expect.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::expectFormatError;
using voxwall::test::expectSameVoxels;
using voxwall::test::patterned;
using voxwall::test::TempDir;

TEST(SliceStack, SliceDirectoryReadsInNaturalOrder) {
  TempDir dir;
  const Volume v = patterned(ScalarType::UInt16, {9, 6, 12});
  std::filesystem::create_directories(dir.path("slices"));
  for (int z = 0; z < v.dims.z; ++z) {
    // Names whose plain sort order is wrong: slice2 after slice10.
    auto out = OIIO::ImageOutput::create("x.png");
    const auto path = dir.path("slices/slice" + std::to_string(z) + ".png");
    OIIO::ImageSpec spec(v.dims.x, v.dims.y, 1, OIIO::TypeDesc::UINT16);
    ASSERT_TRUE(out->open(path, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT16,
                                 v.as<std::uint16_t>().data() + std::size_t(z) * 54));
    out->close();
  }
  const Volume back = readVolume(dir.path("slices"));
  expectSameVoxels(v, back);
}

TEST(SliceStack, MultiPageTiffReadsAsAStack) {
  TempDir dir;
  const Volume v = patterned(ScalarType::UInt8, {10, 4, 3});
  const auto path = dir.path("stack.tif");
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out->supports("multiimage"));
  std::vector<OIIO::ImageSpec> specs(3, OIIO::ImageSpec(10, 4, 1, OIIO::TypeDesc::UINT8));
  ASSERT_TRUE(out->open(path, 3, specs.data()));
  for (int z = 0; z < 3; ++z) {
    if (z) {
      ASSERT_TRUE(out->open(path, specs[0], OIIO::ImageOutput::AppendSubimage));
    }
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, v.as<std::uint8_t>().data() + z * 40));
  }
  out->close();
  expectSameVoxels(v, readVolume(path));
}

TEST(SliceStack, SlicesOfDifferentSizesAreRefused) {
  TempDir dir;
  std::filesystem::create_directories(dir.path("s"));
  for (int z = 0; z < 2; ++z) {
    auto out = OIIO::ImageOutput::create("x.png");
    OIIO::ImageSpec spec(8 + z, 8, 1, OIIO::TypeDesc::UINT8);
    std::vector<unsigned char> px(std::size_t(spec.width) * 8, 1);
    ASSERT_TRUE(out->open(dir.path("s/" + std::to_string(z) + ".png"), spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
  }
  expectFormatError([&] { readVolume(dir.path("s")); }, dir.path("s/1.png"), "first slice");
}
