#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/image.hpp>
#include <voxwall/core/image_files.hpp>

namespace voxwall {

void Image::paste(const Image& tile, const Rect& rect) {
  if (!rect.fitsIn(width, height) || tile.width != rect.width || tile.height != rect.height)
    throw std::invalid_argument("Image::paste: tile does not fit");
  for (int y = 0; y < rect.height; ++y)
    std::copy_n(tile.pixels.begin() + std::ptrdiff_t(y) * tile.width, tile.width,
                pixels.begin() + std::ptrdiff_t(rect.y + y) * width + rect.x);
}

Image Image::crop(const Rect& rect) const {
  if (!rect.fitsIn(width, height))
    throw std::invalid_argument("Image::crop: rectangle outside the image");
  Image out(rect.width, rect.height);
  for (int y = 0; y < rect.height; ++y)
    std::copy_n(pixels.begin() + std::ptrdiff_t(rect.y + y) * width + rect.x, rect.width,
                out.pixels.begin() + std::ptrdiff_t(y) * rect.width);
  return out;
}

std::vector<std::byte> encodeImage(const Image& image, const std::string& path,
                                   const std::optional<glm::dvec3>& background) {
  // Float channels straight from the premultiplied bytes; OIIO converts to the file's type.
  std::vector<float> rgba(image.pixels.size() * 4);
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    const std::uint32_t p = image.pixels[i];
    float c[4] = {float(p & 255) / 255.f, float((p >> 8) & 255) / 255.f,
                  float((p >> 16) & 255) / 255.f, float(p >> 24) / 255.f};
    if (background) {
      for (int k = 0; k < 3; ++k) c[k] += (1.0f - c[3]) * float((*background)[k]);
      c[3] = 1.0f;
    } else if (c[3] > 0.0f) {
      for (int k = 0; k < 3; ++k) c[k] = std::min(1.0f, c[k] / c[3]);
    }
    std::copy(c, c + 4, rgba.begin() + std::ptrdiff_t(i * 4));
  }
  // Encoded in memory: OpenImageIO's writers do not all report a full disk, our writer does.
  std::vector<std::byte> bytes;
  std::string error;
  if (!image_files::api().encodeRgba(path, image.width, image.height, rgba.data(), bytes, error))
    throw FormatError(path, error);
  return bytes;
}

std::vector<std::byte> encodeOpaqueImage(const Image& image, const std::string& path,
                                         const ImageEncoding& encoding) {
  std::vector<std::byte> bytes;
  std::string error;
  if (!image_files::api().encodeRgb8(path, image.width, image.height, image.pixels.data(),
                                     encoding.pngLevel, encoding.jpegQuality, bytes, error))
    throw FormatError(path, error);
  return bytes;
}

voxwall::FileDigest writeImage(const Image& image, const std::string& path,
                               const std::optional<glm::dvec3>& background) {
  const auto bytes = encodeImage(image, path, background);
  voxwall::writeFileAtomically(path, bytes);
  return voxwall::digestOf(bytes);
}

Image readImage(const std::string& path) {
  image_files::Layout spec;
  std::vector<float> data;
  std::string error;
  if (!image_files::api().readFloats(path, spec, data, error)) throw FormatError(path, error);
  if (spec.channels < 3) throw FormatError(path, "not an RGB(A) image");
  Image img(spec.width, spec.height);
  const int n = spec.channels;
  auto q = [](float v) { return std::uint32_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f)); };
  for (std::size_t i = 0; i < img.pixels.size(); ++i) {
    const float* c = &data[i * std::size_t(n)];
    const float a = n >= 4 ? c[3] : 1.0f;
    img.pixels[i] = q(c[0] * a) | (q(c[1] * a) << 8) | (q(c[2] * a) << 16) | (q(a) << 24);
  }
  return img;
}

ImageDiff compareImages(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height)
    throw std::invalid_argument("compareImages: sizes differ");
  ImageDiff d;
  double sum = 0, sq = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i)
    for (int c = 0; c < 4; ++c) {
      const int va = int((a.pixels[i] >> (8 * c)) & 255), vb = int((b.pixels[i] >> (8 * c)) & 255);
      const int diff = std::abs(va - vb);
      d.maxAbs = std::max(d.maxAbs, diff);
      sum += diff;
      sq += double(diff) * diff;
    }
  const double n = double(a.pixels.size()) * 4.0;
  d.meanAbs = n > 0 ? sum / n : 0.0;
  d.psnrDb = sq == 0 ? std::numeric_limits<double>::infinity()
                     : 10.0 * std::log10(255.0 * 255.0 / (sq / n));
  return d;
}

}  // namespace voxwall
