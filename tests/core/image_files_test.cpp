// The image-file module: OpenImageIO is loaded by the first image read or written, not at start.
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/image.hpp>
#include <voxwall/core/image_files.hpp>

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
#ifdef __SANITIZE_ADDRESS__
  // The sanitizer build loads OpenImageIO's libraries with the program (core/CMakeLists.txt
  // says why); the module itself is still loaded by the first image.
  constexpr bool kLoadedAtStart = true;
#else
  constexpr bool kLoadedAtStart = false;
#endif
  if (mapped("libvoxwall_image_files"))
    GTEST_SKIP() << "an earlier test in this process read or wrote an image";
  EXPECT_EQ(mapped("libOpenImageIO"), kLoadedAtStart);
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

// Where the module cannot be loaded, the error names every place tried and why each was passed
// over, and nothing is loaded.
TEST(ImageFiles, AModuleThatCannotBeLoadedIsRefusedNamingEveryPlaceTried) {
  namespace fs = std::filesystem;
  const fs::path dir =
      fs::temp_directory_path() / ("voxwall-no-module-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string missing = (dir / "libvoxwall_image_files.so").string();
  const std::string text = (dir / "text.so").string();
  std::ofstream(text) << "not a shared library";
  Dl_info libc{};
  ASSERT_NE(::dladdr(reinterpret_cast<void*>(&::getpid), &libc), 0);
  const std::string other = libc.dli_fname;  // a library, but not the module
  try {
    voxwall::image_files::loadModule({missing, text, other});
    ADD_FAILURE() << "loaded a module from none";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("cannot load voxwall's image-file module libvoxwall_image_files.so", 0),
              0u)
        << what;
    EXPECT_NE(what.find(missing + " (missing)"), std::string::npos) << what;
    EXPECT_NE(what.find(text + " ("), std::string::npos) << what;
    EXPECT_NE(what.find(other + " (not voxwall's image-file module)"), std::string::npos) << what;
  }
  fs::remove_all(dir);
}
