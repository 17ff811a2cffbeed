#include <turbojpeg.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <utility>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>
#include <voxwall/net/tile_codec.hpp>

namespace voxwall::net {
namespace {

struct TjDeleter {
  void operator()(void* h) const { tjDestroy(h); }
};
using TjHandle = std::unique_ptr<void, TjDeleter>;

// Premultiplied RGBA over an opaque background -> RGB8.
std::vector<unsigned char> compositeRgb(const voxwall::Image& image, const voxwall::Rect& part,
                                        const glm::dvec3& background) {
  std::vector<unsigned char> rgb(std::size_t(part.width) * std::size_t(part.height) * 3);
  const int bg[3] = {int(std::lround(background.r * 255)), int(std::lround(background.g * 255)),
                     int(std::lround(background.b * 255))};
  std::size_t o = 0;
  for (int y = part.y; y < part.y + part.height; ++y)
    for (int x = part.x; x < part.x + part.width; ++x) {
      const std::uint32_t p = image.at(x, y);
      const int a = int(p >> 24);
      for (int c = 0; c < 3; ++c) {
        const int v = int((p >> (8 * c)) & 255u) + (bg[c] * (255 - a) + 127) / 255;
        rgb[o++] = (unsigned char)std::min(v, 255);
      }
    }
  return rgb;
}

int tjSubsampling(Subsampling s) {
  switch (s) {
    case Subsampling::S444:
      return TJSAMP_444;
    case Subsampling::S422:
      return TJSAMP_422;
    case Subsampling::S420:
      return TJSAMP_420;
  }
  return TJSAMP_420;
}

// A compressor and its output buffer, reused across segments and calls: tjInitCompress and the
// worst-case output buffer are allocations we do not want per segment.
struct Compressor {
  TjHandle handle;
  unsigned char* buffer = nullptr;
  unsigned long capacity = 0;
  Compressor() : handle(tjInitCompress()) {
    if (!handle) throw NetError("tjInitCompress failed");
  }
  Compressor(Compressor&& o) noexcept
      : handle(std::move(o.handle)),
        buffer(std::exchange(o.buffer, nullptr)),
        capacity(std::exchange(o.capacity, 0)) {}
  Compressor& operator=(Compressor&&) = delete;
  ~Compressor() { tjFree(buffer); }
};

class CompressorPool {
 public:
  std::unique_ptr<Compressor> take() {
    {
      std::lock_guard lock(mutex_);
      if (!free_.empty()) {
        auto c = std::move(free_.back());
        free_.pop_back();
        return c;
      }
    }
    return std::make_unique<Compressor>();
  }
  void give(std::unique_ptr<Compressor> c) {
    std::lock_guard lock(mutex_);
    if (free_.size() < 64) free_.push_back(std::move(c));
  }

 private:
  std::mutex mutex_;
  std::vector<std::unique_ptr<Compressor>> free_;
};

CompressorPool& compressorPool() {
  static CompressorPool pool;
  return pool;
}

// JPEG of `w` x `h` pixels at `src` (rows `pitch` bytes apart) in TurboJPEG pixel format `format`.
std::vector<std::byte> compressJpeg(const unsigned char* src, int w, int pitch, int h, int format,
                                    const TileCodecSettings& s) {
  auto c = compressorPool().take();
  const int subsamp = tjSubsampling(s.subsampling);
  const unsigned long worst = tjBufSize(w, h, subsamp);
  if (c->capacity < worst) {
    tjFree(c->buffer);
    c->buffer = tjAlloc(int(worst));
    if (!c->buffer) throw NetError("out of memory for a JPEG buffer");
    c->capacity = worst;
  }
  unsigned char* jpeg = c->buffer;
  unsigned long size = c->capacity;
  if (tjCompress2(c->handle.get(), src, w, pitch, h, format, &jpeg, &size, subsamp, s.jpegQuality,
                  TJFLAG_FASTDCT | TJFLAG_NOREALLOC) != 0)
    throw NetError(std::string("JPEG compression failed: ") + tjGetErrorStr2(c->handle.get()));
  std::vector<std::byte> out(size);
  std::memcpy(out.data(), jpeg, size);
  compressorPool().give(std::move(c));
  return out;
}

std::vector<std::byte> encodeSegment(const voxwall::Image& image, const voxwall::Rect& part,
                                     const glm::dvec3& background, const TileCodecSettings& s) {
  if (s.codec == TileCodec::Jpeg && background == glm::dvec3(0.0)) {
    // Premultiplied colour over black is the colour as stored: compress straight from the
    // image (RGBX: the alpha byte is skipped), no copy.
    const auto* src = reinterpret_cast<const unsigned char*>(
        &image.pixels[std::size_t(part.y) * std::size_t(image.width) + std::size_t(part.x)]);
    return compressJpeg(src, part.width, image.width * 4, part.height, TJPF_RGBX, s);
  }
  const auto rgb = compositeRgb(image, part, background);
  std::vector<std::byte> out;
  switch (s.codec) {
    case TileCodec::Raw:
      out.resize(rgb.size());
      std::memcpy(out.data(), rgb.data(), rgb.size());
      return out;
    case TileCodec::Deflate: {
      uLongf size = compressBound(uLong(rgb.size()));
      out.resize(size);
      if (compress2(reinterpret_cast<Bytef*>(out.data()), &size, rgb.data(), uLong(rgb.size()),
                    1) != Z_OK)
        throw NetError("deflate failed");
      out.resize(size);
      return out;
    }
    case TileCodec::Jpeg:
      return compressJpeg(rgb.data(), part.width, 0, part.height, TJPF_RGB, s);
  }
  throw std::invalid_argument("unknown tile codec");
}

}  // namespace

const char* tileCodecName(TileCodec codec) {
  switch (codec) {
    case TileCodec::Jpeg:
      return "jpeg";
    case TileCodec::Raw:
      return "raw";
    case TileCodec::Deflate:
      return "deflate";
  }
  return "unknown";
}

std::vector<EncodedTile> encodeTiles(const voxwall::Image& image, const voxwall::Rect& rect,
                                     const glm::dvec3& background, const TileCodecSettings& s) {
  if (image.width != rect.width || image.height != rect.height)
    throw std::invalid_argument("encodeTiles: image and rectangle differ in size");
  if (s.jpegQuality < 1 || s.jpegQuality > 100)
    throw std::invalid_argument("JPEG quality must be in [1, 100]");
  if (s.segmentPixels < 8) throw std::invalid_argument("segments must be at least 8 pixels");
  std::vector<voxwall::Rect> parts;  // in tile coordinates
  for (int y = 0; y < rect.height; y += s.segmentPixels)
    for (int x = 0; x < rect.width; x += s.segmentPixels)
      parts.push_back({x, y, std::min(s.segmentPixels, rect.width - x),
                       std::min(s.segmentPixels, rect.height - y)});
  std::vector<EncodedTile> out(parts.size());
  voxwall::parallelFor(parts.size(), s.threads, [&](std::size_t i) {
    const voxwall::Rect& p = parts[i];
    out[i].rect = {rect.x + p.x, rect.y + p.y, p.width, p.height};
    out[i].codec = s.codec;
    out[i].bytes = encodeSegment(image, p, background, s);
  });
  return out;
}

voxwall::Image decodeTile(std::span<const std::byte> bytes, TileCodec codec, int width, int height,
                          const std::string& source) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
    throw FormatError(source, "tile size " + std::to_string(width) + "x" + std::to_string(height));
  const std::size_t pixels = std::size_t(width) * std::size_t(height);
  voxwall::Image image(width, height);
  auto fromRgb = [&](const unsigned char* rgb) {
    for (std::size_t i = 0; i < pixels; ++i)
      image.pixels[i] = std::uint32_t(rgb[3 * i]) | std::uint32_t(rgb[3 * i + 1]) << 8 |
                        std::uint32_t(rgb[3 * i + 2]) << 16 | 0xff000000u;
  };
  switch (codec) {
    case TileCodec::Raw:
      if (bytes.size() != pixels * 3)
        throw FormatError(source, "raw tile of " + std::to_string(bytes.size()) + " bytes for " +
                                      std::to_string(pixels) + " pixels");
      fromRgb(reinterpret_cast<const unsigned char*>(bytes.data()));
      return image;
    case TileCodec::Deflate: {
      std::vector<unsigned char> rgb(pixels * 3);
      uLongf size = uLongf(rgb.size());
      if (uncompress(rgb.data(), &size, reinterpret_cast<const Bytef*>(bytes.data()),
                     uLong(bytes.size())) != Z_OK ||
          size != rgb.size())
        throw FormatError(source, "corrupt deflate tile");
      fromRgb(rgb.data());
      return image;
    }
    case TileCodec::Jpeg: {
      TjHandle tj(tjInitDecompress());
      if (!tj) throw NetError("tjInitDecompress failed");
      int w = 0, h = 0, subsamp = 0, colorspace = 0;
      auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
      if (tjDecompressHeader3(tj.get(), data, (unsigned long)bytes.size(), &w, &h, &subsamp,
                              &colorspace) != 0)
        throw FormatError(source, std::string("corrupt JPEG tile: ") + tjGetErrorStr2(tj.get()));
      if (w != width || h != height)
        throw FormatError(source, "JPEG tile is " + std::to_string(w) + "x" + std::to_string(h) +
                                      ", the message says " + std::to_string(width) + "x" +
                                      std::to_string(height));
      if (tjDecompress2(tj.get(), data, (unsigned long)bytes.size(),
                        reinterpret_cast<unsigned char*>(image.pixels.data()), width, 0, height,
                        TJPF_RGBA, TJFLAG_FASTDCT | TJFLAG_STOPONWARNING) != 0)
        throw FormatError(source, std::string("corrupt JPEG tile: ") + tjGetErrorStr2(tj.get()));
      for (auto& p : image.pixels) p |= 0xff000000u;
      return image;
    }
  }
  throw FormatError(source, "unknown tile codec " + std::to_string(int(codec)));
}

}  // namespace voxwall::net
