#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/image.hpp>

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
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw FormatError(path, "cannot write images of this type: " + OIIO::geterror());
  if (!out->supports("ioproxy"))
    throw FormatError(path, "cannot write " + std::string(out->format_name()) + " images safely");
  const bool exr = out->format_name() == std::string("openexr");
  OIIO::ImageSpec spec(image.width, image.height, 4,
                       exr ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::UINT8);
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput memory(encoded);
  if (!out->set_ioproxy(&memory) || !out->open(path, spec) ||
      !out->write_image(OIIO::TypeDesc::FLOAT, rgba.data()) || !out->close())
    throw FormatError(path, "cannot encode image: " + out->geterror());
  std::vector<std::byte> bytes(encoded.size());
  std::memcpy(bytes.data(), encoded.data(), encoded.size());
  return bytes;
}

std::vector<std::byte> encodeOpaqueImage(const Image& image, const std::string& path,
                                         const ImageEncoding& encoding) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw FormatError(path, "cannot write images of this type: " + OIIO::geterror());
  if (!out->supports("ioproxy"))
    throw FormatError(path, "cannot write " + std::string(out->format_name()) + " images safely");
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("png:compressionLevel", std::clamp(encoding.pngLevel, 0, 9));
  // libpng's "up" filter alone (PNG_FILTER_UP): on bigeye frames of a volume it encoded 2.4x
  // faster than the default adaptive choice among all five filters, and the files were no
  // bigger (measured with bench/wall_fps.py's --out runs).
  constexpr int kPngFilterUp = 0x20;
  spec.attribute("png:filter", kPngFilterUp);
  spec.attribute("Compression", "jpeg:" + std::to_string(std::clamp(encoding.jpegQuality, 1, 100)));
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput memory(encoded);
  // RGB from RGBA in place: 4 bytes between pixels, the alpha byte skipped.
  if (!out->set_ioproxy(&memory) || !out->open(path, spec) ||
      !out->write_image(OIIO::TypeDesc::UINT8, image.pixels.data(), 4) || !out->close())
    throw FormatError(path, "cannot encode image: " + out->geterror());
  std::vector<std::byte> bytes(encoded.size());
  std::memcpy(bytes.data(), encoded.data(), encoded.size());
  return bytes;
}

voxwall::FileDigest writeImage(const Image& image, const std::string& path,
                               const std::optional<glm::dvec3>& background) {
  const auto bytes = encodeImage(image, path, background);
  voxwall::writeFileAtomically(path, bytes);
  return voxwall::digestOf(bytes);
}

Image readImage(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw FormatError(path, "cannot open image: " + OIIO::geterror());
  const auto& spec = in->spec();
  if (spec.nchannels < 3) throw FormatError(path, "not an RGB(A) image");
  std::vector<float> data(std::size_t(spec.width) * std::size_t(spec.height) *
                          std::size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, data.data()))
    throw FormatError(path, "cannot read image: " + in->geterror());
  Image img(spec.width, spec.height);
  const int n = spec.nchannels;
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
