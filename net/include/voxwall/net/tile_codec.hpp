// The frame codec: a rendered tile becomes opaque RGB (composited onto the wall's background,
// since JPEG has no alpha) and is compressed in segments, in parallel, on the rank that rendered
// it (libjpeg-turbo through the TurboJPEG API; or raw / deflate for exact output).
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>
#include <voxwall/core/image.hpp>

namespace voxwall::net {

// Values are on the wire: never reuse one.
enum class TileCodec : std::uint8_t { Jpeg = 1, Raw = 2, Deflate = 3 };
enum class Subsampling { S444, S422, S420 };

struct TileCodecSettings {
  TileCodec codec = TileCodec::Jpeg;
  int jpegQuality = 90;  // 1..100
  Subsampling subsampling = Subsampling::S420;
  int segmentPixels = 1024;  // segments are at most this wide and high
  int threads = 0;           // 0: the usable cores
};

struct EncodedTile {
  voxwall::Rect rect;  // in virtual-screen pixels
  TileCodec codec = TileCodec::Jpeg;
  std::vector<std::byte> bytes;
};

// Splits `image` (premultiplied RGBA, placed at `rect` on the virtual screen) into segments,
// composites them onto `background` and compresses them in parallel. Throws NetError on a
// libjpeg-turbo failure, std::invalid_argument on bad settings.
std::vector<EncodedTile> encodeTiles(const voxwall::Image& image, const voxwall::Rect& rect,
                                     const glm::dvec3& background,
                                     const TileCodecSettings& settings);

// Decodes one tile into an opaque image of rect's size. Throws FormatError("<source>: ...")
// when the bytes are corrupt or do not decode to exactly that size.
voxwall::Image decodeTile(std::span<const std::byte> bytes, TileCodec codec, int width, int height,
                          const std::string& source);

const char* tileCodecName(TileCodec codec);

// A network, transport or protocol failure (a peer that vanished, a refused connection).
class NetError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};
// The sink answered and refused this peer (wrong token, wall, job or protocol version): trying
// again cannot help, unlike a sink that is down or restarting.
class SinkRefused : public NetError {
  using NetError::NetError;
};

}  // namespace voxwall::net
