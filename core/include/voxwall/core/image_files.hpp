// Image files through OpenImageIO, loaded on first use. OpenImageIO and the ~260 libraries it
// links (codecs, OpenCV, FFmpeg, OpenVDB, ...) cost every process about 0.3 s of CPU to load and
// initialise, which every voxwall command, MPI rank and test program paid at start even when it
// never touched an image. The code that calls OpenImageIO is a module of its own
// (libvoxwall_image_files.so, core/src/image_files_module.cpp) that the first image read or
// written loads, from beside the running program or from where the build put it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace voxwall::image_files {

// What the module does; every function returns false with `error` set instead of throwing.
// Shared by core (image.cpp) and the module, which are built together: plain C++ types only.
enum class Pixel : int { UInt8, UInt16, Int16, Float32, Other };

struct Layout {
  int width = 0, height = 0, depth = 1, channels = 0;
  Pixel format = Pixel::Other;
};

struct Api {
  int version;
  // RGBA floats (straight alpha) encoded in memory as `path`'s file type (EXR as half float,
  // others as 8 bits).
  bool (*encodeRgba)(const std::string& path, int width, int height, const float* rgba,
                     std::vector<std::byte>& out, std::string& error);
  // The RGB bytes of RGBA pixels (4 bytes apart) encoded as 8-bit RGB in `path`'s file type.
  bool (*encodeRgb8)(const std::string& path, int width, int height, const std::uint32_t* rgba,
                     int pngLevel, int jpegQuality, std::vector<std::byte>& out,
                     std::string& error);
  // A whole image as floats, all its channels (`layout.channels` per pixel).
  bool (*readFloats)(const std::string& path, Layout& layout, std::vector<float>& data,
                     std::string& error);
  // A file open for reading subimage by subimage (multi-page TIFF): an opaque handle.
  void* (*open)(const std::string& path, std::string& error);
  // The layout of subimage `index`; false when there is none.
  bool (*subimage)(void* file, int index, Layout& layout);
  // Channel 0 of subimage `index` as `type` into `dst` (width x height values).
  bool (*readChannel0)(void* file, int index, Pixel type, void* dst, std::string& error);
  void (*close)(void* file);
};

inline constexpr int kApiVersion = 1;
inline constexpr const char* kModuleFile = "libvoxwall_image_files.so";
inline constexpr const char* kEntryPoint = "voxwall_image_files_api";

// The module's functions, loading it on the first call; throws std::runtime_error naming where
// it looked when it cannot be loaded.
const Api& api();

// Loads the first of `paths` that is voxwall's image-file module of this version; otherwise
// throws std::runtime_error naming every path and why it was passed over (missing, not
// loadable, not the module, another version). api() calls it with its two places.
const Api& loadModule(const std::vector<std::string>& paths);

// An image file open for reading, subimage by subimage; throws FormatError("<path>: ...").
class Reader {
 public:
  explicit Reader(const std::string& path);
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;
  bool subimage(int index, Layout& layout) const;  // false when there is no such subimage
  void readChannel0(int index, Pixel type, void* dst, const std::string& what) const;

 private:
  std::string path_;
  void* file_ = nullptr;
};

}  // namespace voxwall::image_files
