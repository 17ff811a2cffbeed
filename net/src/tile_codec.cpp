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
#include <voxwall/net/wire.hpp>

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

namespace {

// The cut positions of [begin, end) along one axis: its ends, every display edge inside it (at
// step > 1 divided by the step, rounded down), then pieces of at most `most`.
std::vector<int> cutPositions(int begin, int end, int most, const std::vector<int>& edges) {
  std::vector<int> at{begin, end};
  for (const int e : edges)
    if (e > begin && e < end) at.push_back(e);
  std::sort(at.begin(), at.end());
  at.erase(std::unique(at.begin(), at.end()), at.end());
  std::vector<int> out;
  for (std::size_t i = 0; i + 1 < at.size(); ++i)
    for (int p = at[i]; p < at[i + 1]; p += most) out.push_back(p);
  out.push_back(end);
  return out;
}

}  // namespace

std::vector<voxwall::Rect> segmentRects(const voxwall::Rect& rect, int segmentPixels,
                                        const DisplayCut& cut, int step) {
  if (segmentPixels < 8) throw std::invalid_argument("segments must be at least 8 pixels");
  if (step < 1) throw std::invalid_argument("segmentRects: step must be at least 1");
  std::vector<int> xEdges, yEdges;
  for (const auto& d : cut.displays) {
    xEdges.push_back(d.x / step), xEdges.push_back((d.x + d.width) / step);
    yEdges.push_back(d.y / step), yEdges.push_back((d.y + d.height) / step);
  }
  const auto xs = cutPositions(rect.x, rect.x + rect.width, segmentPixels, xEdges);
  const auto ys = cutPositions(rect.y, rect.y + rect.height, segmentPixels, yEdges);
  const bool all = cut.bezels || cut.displays.empty();
  std::vector<voxwall::Rect> out;
  for (std::size_t j = 0; j + 1 < ys.size(); ++j)
    for (std::size_t i = 0; i + 1 < xs.size(); ++i) {
      const voxwall::Rect part{xs[i], ys[j], xs[i + 1] - xs[i], ys[j + 1] - ys[j]};
      if (all) {
        out.push_back(part);
        continue;
      }
      const auto shown = fullScreenRect(part, step, cut.screenWidth, cut.screenHeight);
      if (std::any_of(cut.displays.begin(), cut.displays.end(),
                      [&](const voxwall::Rect& d) { return shown.overlaps(d); }))
        out.push_back(part);
    }
  return out;
}

std::vector<EncodedTile> encodeTiles(const voxwall::Image& image, const voxwall::Rect& rect,
                                     const glm::dvec3& background, const TileCodecSettings& s,
                                     const DisplayCut& cut, int step) {
  if (image.width != rect.width || image.height != rect.height)
    throw std::invalid_argument("encodeTiles: image and rectangle differ in size");
  if (s.jpegQuality < 1 || s.jpegQuality > 100)
    throw std::invalid_argument("JPEG quality must be in [1, 100]");
  const auto parts = segmentRects(rect, s.segmentPixels, cut, step);
  std::vector<EncodedTile> out(parts.size());
  voxwall::parallelFor(parts.size(), s.threads, [&](std::size_t i) {
    const voxwall::Rect& p = parts[i];
    out[i].rect = p;
    out[i].codec = s.codec;
    out[i].bytes =
        encodeSegment(image, {p.x - rect.x, p.y - rect.y, p.width, p.height}, background, s);
  });
  return out;
}

namespace {

void checkTileSize(int width, int height, const std::string& source) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
    throw FormatError(source, "tile size " + std::to_string(width) + "x" + std::to_string(height));
}

// Each thread's TurboJPEG decompressor, kept: tjInitDecompress allocates.
tjhandle threadDecompressor() {
  thread_local TjHandle handle(tjInitDecompress());
  if (!handle) throw NetError("tjInitDecompress failed");
  return handle.get();
}

void checkJpegHeader(tjhandle tj, std::span<const std::byte> bytes, int width, int height,
                     const std::string& source) {
  int w = 0, h = 0, subsamp = 0, colorspace = 0;
  if (tjDecompressHeader3(tj, reinterpret_cast<const unsigned char*>(bytes.data()),
                          (unsigned long)bytes.size(), &w, &h, &subsamp, &colorspace) != 0)
    throw FormatError(source, std::string("corrupt JPEG tile: ") + tjGetErrorStr2(tj));
  if (w != width || h != height)
    throw FormatError(source, "JPEG tile is " + std::to_string(w) + "x" + std::to_string(h) +
                                  ", the message says " + std::to_string(width) + "x" +
                                  std::to_string(height));
}

// Inflates a deflate tile, handing each piece of output to `take`; checks that it is one whole
// zlib stream of exactly `expected` bytes with nothing after it.
template <typename Take>
void inflateTile(std::span<const std::byte> bytes, std::size_t expected, const std::string& source,
                 Take take) {
  z_stream z{};
  if (inflateInit(&z) != Z_OK) throw NetError("inflateInit failed");
  std::unique_ptr<z_stream, int (*)(z_stream*)> guard(&z, inflateEnd);
  z.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(bytes.data()));
  z.avail_in = uInt(bytes.size());
  unsigned char chunk[1 << 16];
  std::size_t produced = 0;
  int rc = Z_OK;
  while (rc == Z_OK) {
    z.next_out = chunk;
    z.avail_out = sizeof chunk;
    rc = inflate(&z, Z_NO_FLUSH);
    const std::size_t n = sizeof chunk - z.avail_out;
    if (produced + n > expected) break;
    take(chunk, produced, n);
    produced += n;
  }  // Z_BUF_ERROR: the stream ended early (every call has fresh room for output)
  if (rc != Z_STREAM_END || produced != expected || z.avail_in != 0)
    throw FormatError(source, "corrupt deflate tile");
}

}  // namespace

voxwall::Image decodeTile(std::span<const std::byte> bytes, TileCodec codec, int width, int height,
                          const std::string& source) {
  return decodeTileScaled(bytes, codec, width, height, 1, source);
}

voxwall::Image decodeTileScaled(std::span<const std::byte> bytes, TileCodec codec, int width,
                                int height, int denominator, const std::string& source) {
  checkTileSize(width, height, source);
  if (denominator != 1 &&
      (codec != TileCodec::Jpeg || (denominator != 2 && denominator != 4 && denominator != 8)))
    throw std::invalid_argument("decodeTileScaled: only JPEG tiles scale, by 1/2, 1/4 or 1/8");
  const std::size_t pixels = std::size_t(width) * std::size_t(height);
  auto fromRgb = [](const unsigned char* rgb, std::uint32_t* out, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i)
      out[i] = std::uint32_t(rgb[3 * i]) | std::uint32_t(rgb[3 * i + 1]) << 8 |
               std::uint32_t(rgb[3 * i + 2]) << 16 | 0xff000000u;
  };
  switch (codec) {
    case TileCodec::Raw: {
      if (bytes.size() != pixels * 3)
        throw FormatError(source, "raw tile of " + std::to_string(bytes.size()) + " bytes for " +
                                      std::to_string(pixels) + " pixels");
      voxwall::Image image(width, height);
      fromRgb(reinterpret_cast<const unsigned char*>(bytes.data()), image.pixels.data(), pixels);
      return image;
    }
    case TileCodec::Deflate: {
      std::vector<unsigned char> rgb(pixels * 3);
      inflateTile(bytes, rgb.size(), source,
                  [&](const unsigned char* chunk, std::size_t at, std::size_t n) {
                    std::memcpy(rgb.data() + at, chunk, n);
                  });
      voxwall::Image image(width, height);
      fromRgb(rgb.data(), image.pixels.data(), pixels);
      return image;
    }
    case TileCodec::Jpeg: {
      const tjhandle tj = threadDecompressor();
      checkJpegHeader(tj, bytes, width, height, source);
      const int w = (width + denominator - 1) / denominator;
      const int h = (height + denominator - 1) / denominator;
      voxwall::Image image(w, h);
      if (tjDecompress2(tj, reinterpret_cast<const unsigned char*>(bytes.data()),
                        (unsigned long)bytes.size(),
                        reinterpret_cast<unsigned char*>(image.pixels.data()), w, 0, h, TJPF_RGBA,
                        TJFLAG_FASTDCT | TJFLAG_STOPONWARNING) != 0)
        throw FormatError(source, std::string("corrupt JPEG tile: ") + tjGetErrorStr2(tj));
      for (auto& p : image.pixels) p |= 0xff000000u;
      return image;
    }
  }
  throw FormatError(source, "unknown tile codec " + std::to_string(int(codec)));
}

void checkTile(std::span<const std::byte> bytes, TileCodec codec, int width, int height,
               const std::string& source) {
  checkTileSize(width, height, source);
  const std::size_t rgbBytes = std::size_t(width) * std::size_t(height) * 3;
  switch (codec) {
    case TileCodec::Raw:
      if (bytes.size() != rgbBytes)
        throw FormatError(source, "raw tile of " + std::to_string(bytes.size()) + " bytes for " +
                                      std::to_string(rgbBytes / 3) + " pixels");
      return;
    case TileCodec::Deflate:
      inflateTile(bytes, rgbBytes, source, [](const unsigned char*, std::size_t, std::size_t) {});
      return;
    case TileCodec::Jpeg:
      checkJpegHeader(threadDecompressor(), bytes, width, height, source);
      return;
  }
  throw FormatError(source, "unknown tile codec " + std::to_string(int(codec)));
}

}  // namespace voxwall::net
