// The image-file module: OpenImageIO is loaded by the first image read or written, not at start.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/image.hpp>

namespace {

// Whether a library whose file name holds `name` is mapped into this process.
bool mapped(const std::string& name) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
    if (line.find(name) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST(ImageFiles, OpenImageIOIsLoadedByTheFirstImageWrittenAndTheImageReadsBack) {
  if (mapped("libOpenImageIO"))
    GTEST_SKIP() << "an earlier test in this process read or wrote an image";
  EXPECT_FALSE(mapped("libvoxwall_image_files"));
  const auto path = (std::filesystem::temp_directory_path() /
                     ("voxwall-image-files-" + std::to_string(::getpid()) + ".png"))
                        .string();
  voxwall::Image image(3, 2);
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    image.pixels[i] = 0xff000000u | std::uint32_t(40 * i) | (std::uint32_t(200 - 30 * i) << 8);
  voxwall::writeImage(image, path);
  EXPECT_TRUE(mapped("libvoxwall_image_files"));
  EXPECT_TRUE(mapped("libOpenImageIO"));
  const voxwall::Image back = voxwall::readImage(path);
  std::filesystem::remove(path);
  EXPECT_EQ(back.width, 3);
  EXPECT_EQ(back.height, 2);
  EXPECT_EQ(back.pixels, image.pixels);
}

TEST(ImageFiles, AFileThatIsNoImageIsRefusedNamingIt) {
  const auto path = (std::filesystem::temp_directory_path() /
                     ("voxwall-not-an-image-" + std::to_string(::getpid()) + ".png"))
                        .string();
  std::ofstream(path) << "not a png";
  try {
    voxwall::readImage(path);
    ADD_FAILURE() << "read a file that is no image";
  } catch (const voxwall::FormatError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
  }
  std::filesystem::remove(path);
}
