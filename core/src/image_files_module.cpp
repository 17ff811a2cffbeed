// The image-file module (libvoxwall_image_files.so): the only code that calls OpenImageIO, loaded
// by the first image read or written (voxwall/core/image_files.hpp says why). Nothing here
// throws across the module's edge: errors come back as text.
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <voxwall/core/image_files.hpp>

namespace {

using voxwall::image_files::Layout;
using voxwall::image_files::Pixel;

Pixel pixelOf(const OIIO::TypeDesc& t) {
  if (t == OIIO::TypeDesc::UINT8) return Pixel::UInt8;
  if (t == OIIO::TypeDesc::UINT16) return Pixel::UInt16;
  if (t == OIIO::TypeDesc::INT16) return Pixel::Int16;
  if (t == OIIO::TypeDesc::FLOAT) return Pixel::Float32;
  return Pixel::Other;
}

OIIO::TypeDesc typeOf(Pixel p) {
  switch (p) {
    case Pixel::UInt8:
      return OIIO::TypeDesc::UINT8;
    case Pixel::UInt16:
      return OIIO::TypeDesc::UINT16;
    case Pixel::Int16:
      return OIIO::TypeDesc::INT16;
    case Pixel::Float32:
    case Pixel::Other:
      break;
  }
  return OIIO::TypeDesc::FLOAT;
}

Layout layoutOf(const OIIO::ImageSpec& spec) {
  Layout l;
  l.width = spec.width, l.height = spec.height, l.depth = std::max(1, spec.depth);
  l.channels = spec.nchannels;
  l.format = pixelOf(spec.format);
  return l;
}

// An ImageOutput for `path` that writes into memory (OpenImageIO's writers do not all report a
// full disk; the caller's atomic writer does), or null with `error` set.
std::unique_ptr<OIIO::ImageOutput> memoryOutput(const std::string& path, std::string& error) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out) {
    error = "cannot write images of this type: " + OIIO::geterror();
    return nullptr;
  }
  if (!out->supports("ioproxy")) {
    error = "cannot write " + std::string(out->format_name()) + " images safely";
    return nullptr;
  }
  return out;
}

bool finish(OIIO::ImageOutput& out, std::vector<unsigned char>& encoded, std::vector<std::byte>& to,
            bool written, std::string& error) {
  if (!written || !out.close()) {
    error = "cannot encode image: " + out.geterror();
    return false;
  }
  to.resize(encoded.size());
  std::memcpy(to.data(), encoded.data(), encoded.size());
  return true;
}

bool encodeRgba(const std::string& path, int width, int height, const float* rgba,
                std::vector<std::byte>& to, std::string& error) {
  auto out = memoryOutput(path, error);
  if (!out) return false;
  const bool exr = out->format_name() == std::string("openexr");
  OIIO::ImageSpec spec(width, height, 4, exr ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::UINT8);
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput memory(encoded);
  const bool written = out->set_ioproxy(&memory) && out->open(path, spec) &&
                       out->write_image(OIIO::TypeDesc::FLOAT, rgba);
  return finish(*out, encoded, to, written, error);
}

bool encodeRgb8(const std::string& path, int width, int height, const std::uint32_t* rgba,
                int pngLevel, int jpegQuality, std::vector<std::byte>& to, std::string& error) {
  auto out = memoryOutput(path, error);
  if (!out) return false;
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("png:compressionLevel", std::clamp(pngLevel, 0, 9));
  // libpng's "up" filter alone (PNG_FILTER_UP): on bigeye frames of a volume it encoded 2.4x
  // faster than the default adaptive choice among all five filters, and the files were no
  // bigger (measured with bench/wall_fps.py's --out runs).
  constexpr int kPngFilterUp = 0x20;
  spec.attribute("png:filter", kPngFilterUp);
  spec.attribute("Compression", "jpeg:" + std::to_string(std::clamp(jpegQuality, 1, 100)));
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput memory(encoded);
  // RGB from RGBA in place: 4 bytes between pixels, the alpha byte skipped.
  const bool written = out->set_ioproxy(&memory) && out->open(path, spec) &&
                       out->write_image(OIIO::TypeDesc::UINT8, rgba, 4);
  return finish(*out, encoded, to, written, error);
}

bool readFloats(const std::string& path, Layout& layout, std::vector<float>& data,
                std::string& error) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    error = "cannot open image: " + OIIO::geterror();
    return false;
  }
  const auto& spec = in->spec();
  layout = layoutOf(spec);
  data.assign(std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(spec.nchannels),
              0.0f);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, data.data())) {
    error = "cannot read image: " + in->geterror();
    return false;
  }
  return true;
}

void* openFile(const std::string& path, std::string& error) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    error = "cannot open image: " + OIIO::geterror();
    return nullptr;
  }
  return in.release();
}

bool subimage(void* file, int index, Layout& layout) {
  auto* in = static_cast<OIIO::ImageInput*>(file);
  if (!in->seek_subimage(index, 0)) return false;
  layout = layoutOf(in->spec());
  return true;
}

bool readChannel0(void* file, int index, Pixel type, void* dst, std::string& error) {
  auto* in = static_cast<OIIO::ImageInput*>(file);
  if (!in->read_image(index, 0, 0, 1, typeOf(type), dst)) {
    error = "cannot read pixels: " + in->geterror();
    return false;
  }
  return true;
}

void closeFile(void* file) { delete static_cast<OIIO::ImageInput*>(file); }

const voxwall::image_files::Api kApi{voxwall::image_files::kApiVersion,
                                     encodeRgba,
                                     encodeRgb8,
                                     readFloats,
                                     openFile,
                                     subimage,
                                     readChannel0,
                                     closeFile};

}  // namespace

extern "C" __attribute__((visibility("default"))) const voxwall::image_files::Api*
voxwall_image_files_api() {
  return &kApi;
}
