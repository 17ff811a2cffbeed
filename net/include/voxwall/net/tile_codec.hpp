// The frame codec: a rendered tile becomes opaque RGB (composited onto the wall's background,
// since JPEG has no alpha) and is compressed in segments, in parallel, on the rank that rendered
// it (libjpeg-turbo through the TurboJPEG API; or raw / deflate for exact output).
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <string>
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

// Where a rank cuts a frame into segments and which segments it sends, as the sink asks in its
// Welcome: segments are cut at every display edge (and every segmentPixels), so each lies wholly
// on the displays it touches or wholly in a bezel gap, and the sink can forward it to those
// displays' pages as it arrived, without decoding it. Segments that no display shows are sent
// only when `bezels` is set (the sink writes the whole virtual screen, --mosaic).
struct DisplayCut {
  int screenWidth = 0, screenHeight = 0;  // the virtual screen
  std::vector<voxwall::Rect> displays;    // virtual-screen pixels; empty: no display edges known
  bool bezels = true;                     // also send segments that lie on no display
};

// The segments of `rect`, a rectangle of a frame's screen (the virtual screen at step 1, the
// reduced screen of an interactive frame at step > 1, whose display edges are the virtual ones
// divided by the step, rounded down): cut at every display edge inside it, then into pieces of at
// most segmentPixels a side, without the ones `cut` does not want. Row by row from the top left.
std::vector<voxwall::Rect> segmentRects(const voxwall::Rect& rect, int segmentPixels,
                                        const DisplayCut& cut = {}, int step = 1);

struct EncodedTile {
  voxwall::Rect rect;  // in virtual-screen pixels
  TileCodec codec = TileCodec::Jpeg;
  std::vector<std::byte> bytes;
};

// Splits `image` (premultiplied RGBA, placed at `rect` on the frame's screen) into the segments
// segmentRects() gives, composites them onto `background` and compresses them in parallel.
// Throws NetError on a libjpeg-turbo failure, std::invalid_argument on bad settings.
std::vector<EncodedTile> encodeTiles(const voxwall::Image& image, const voxwall::Rect& rect,
                                     const glm::dvec3& background,
                                     const TileCodecSettings& settings, const DisplayCut& cut = {},
                                     int step = 1);

// Decodes one tile into an opaque image of rect's size. Throws FormatError("<source>: ...")
// when the bytes are corrupt or do not decode to exactly that size.
voxwall::Image decodeTile(std::span<const std::byte> bytes, TileCodec codec, int width, int height,
                          const std::string& source);
// The same, scaled down by `denominator` (1, 2, 4 or 8) in the JPEG decoder itself (its DCT
// scaling: a fraction of the work of a full decode): an image of ceil(width / d) x ceil(height /
// d). Raw and deflate tiles are decoded whole and `denominator` must be 1 for them.
voxwall::Image decodeTileScaled(std::span<const std::byte> bytes, TileCodec codec, int width,
                                int height, int denominator, const std::string& source);

// The cheap check the sink makes of a tile it forwards without decoding it: a JPEG's header
// describes exactly width x height pixels, a raw tile holds width * height * 3 bytes, a deflate
// stream inflates to exactly that many (inflated into a small scratch buffer, not kept). Throws
// FormatError naming what disagrees. A JPEG whose entropy-coded body is corrupt passes; the
// displays' pages decode it and report it.
void checkTile(std::span<const std::byte> bytes, TileCodec codec, int width, int height,
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
