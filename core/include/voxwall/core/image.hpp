// RGBA8 image buffers and image files.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/core/files.hpp>
#include <voxwall/core/rect.hpp>

namespace voxwall {

// Premultiplied RGBA8, row 0 at the top, one uint32 per pixel with red in the lowest byte.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint32_t> pixels;

  Image() = default;
  Image(int w, int h) : width(w), height(h), pixels(std::size_t(w) * std::size_t(h), 0u) {}
  std::uint32_t& at(int x, int y) {
    return pixels[std::size_t(y) * std::size_t(width) + std::size_t(x)];
  }
  std::uint32_t at(int x, int y) const {
    return pixels[std::size_t(y) * std::size_t(width) + std::size_t(x)];
  }
  // Copies `tile` (of size rect.width x rect.height) into this image at rect's position.
  void paste(const Image& tile, const Rect& rect);
  // The sub-image at `rect`; throws std::invalid_argument if it is not inside the image.
  Image crop(const Rect& rect) const;
};

// Encodes a PNG (8-bit) or another format OpenImageIO knows from the extension of `path` (EXR
// as half float) in memory. Colours are un-premultiplied (straight alpha in files); with a
// background colour the image is composited onto it and written opaque. Throws FormatError.
std::vector<std::byte> encodeImage(const Image& image, const std::string& path,
                                   const std::optional<glm::dvec3>& background = std::nullopt);
// encodeImage, then writeFileAtomically: a full disk or a killed writer never leaves a
// partial file under `path`. Returns the size and hash of what was written. Throws
// FormatError("<path>: ...") naming the reason.
FileDigest writeImage(const Image& image, const std::string& path,
                      const std::optional<glm::dvec3>& background = std::nullopt);
// How encodeOpaqueImage compresses: PNG's zlib level (0-9; 1 by default: the sink's files must
// keep up with the wall) and JPEG's quality.
struct ImageEncoding {
  int pngLevel = 1;
  int jpegQuality = 95;
};
// Encodes an opaque image (every alpha 255: decoded wall frames) as 8-bit RGB, in memory, in the
// format of `path`'s extension (PNG or JPEG), straight from the RGBA bytes: no float copy, no
// un-premultiplying. Throws FormatError.
std::vector<std::byte> encodeOpaqueImage(const Image& image, const std::string& path,
                                         const ImageEncoding& encoding = {});
// Reads an 8-bit RGBA (or RGB) image written by writeImage back into premultiplied form.
Image readImage(const std::string& path);

// Image comparison for tests and benchmarks, over all four channels.
struct ImageDiff {
  int maxAbs = 0;        // largest channel difference, 0..255
  double meanAbs = 0.0;  // mean channel difference
  double psnrDb = 0.0;   // +inf when identical
};
ImageDiff compareImages(const Image& a, const Image& b);  // throws on a size mismatch

}  // namespace voxwall
