#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <voxwall/core/parallel.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/walls/frame_pixels.hpp>

namespace voxwall::walls {

namespace {

long long ceilDiv(long long a, long long b) { return a >= 0 ? (a + b - 1) / b : -((-a) / b); }

voxwall::Rect intersection(const voxwall::Rect& a, const voxwall::Rect& b) {
  const int x0 = std::max(a.x, b.x), y0 = std::max(a.y, b.y);
  const int x1 = std::min(a.x + a.width, b.x + b.width);
  const int y1 = std::min(a.y + a.height, b.y + b.height);
  return {x0, y0, std::max(0, x1 - x0), std::max(0, y1 - y0)};
}

// The decoded pixels of one segment that touch the region.
struct Decoded {
  const Segment* segment = nullptr;
  int denominator = 1;  // the JPEG decoder's scaling: 1/denominator
  voxwall::Image pixels;
};

// Output pixels [first, last) along one axis whose block centres lie in [begin, end) (virtual
// pixels), for an output whose pixel 0 starts at `origin` and spans `scale` virtual pixels; and
// for each, the decoded pixel it shows: decoded pixel 0 starts at `sourceOrigin` and spans `span`
// virtual pixels. Centres are counted in half pixels so that everything stays in integers.
std::vector<int> sourceIndices(int origin, int scale, int begin, int end, int outSize,
                               long long sourceOrigin, long long span, int sourceSize, int* first) {
  const long long lo =
      std::clamp<long long>(ceilDiv(2ll * (begin - origin) - scale, 2ll * scale), 0, outSize);
  const long long hi =
      std::clamp<long long>(ceilDiv(2ll * (end - origin) - scale, 2ll * scale), 0, outSize);
  std::vector<int> out;
  for (long long i = lo; i < hi; ++i) {
    const long long centre2 = 2ll * origin + (2 * i + 1) * scale;
    out.push_back(
        int(std::clamp<long long>((centre2 - 2 * sourceOrigin) / (2 * span), 0, sourceSize - 1)));
  }
  *first = int(lo);
  return out;
}

void paint(voxwall::Image& out, const voxwall::Rect& region, int scale, int step,
           const Decoded& d) {
  const Segment& s = *d.segment;
  const voxwall::Rect v = intersection(s.screen, region);
  if (v.width <= 0 || v.height <= 0) return;
  const long long span = (long long)step * d.denominator;
  int x0 = 0, y0 = 0;
  const auto xs = sourceIndices(region.x, scale, v.x, v.x + v.width, out.width,
                                (long long)s.rect.x * step, span, d.pixels.width, &x0);
  const auto ys = sourceIndices(region.y, scale, v.y, v.y + v.height, out.height,
                                (long long)s.rect.y * step, span, d.pixels.height, &y0);
  if (xs.empty() || ys.empty()) return;  // thinner than an output pixel's centre spacing
  for (std::size_t j = 0; j < ys.size(); ++j) {
    std::uint32_t* row = &out.at(x0, y0 + int(j));
    const std::uint32_t* src = &d.pixels.pixels[std::size_t(ys[j]) * std::size_t(d.pixels.width)];
    if (span == 1 && scale == 1) {  // the common case: a straight copy
      std::copy_n(src + xs.front(), xs.size(), row);
      continue;
    }
    for (std::size_t i = 0; i < xs.size(); ++i) row[i] = src[xs[i]];
  }
}

}  // namespace

std::uint32_t backgroundPixel(const glm::dvec3& background) {
  auto channel = [](double v) {
    return std::uint32_t(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
  };
  return channel(background.r) | channel(background.g) << 8 | channel(background.b) << 16 |
         0xff000000u;
}

voxwall::Image decodeRegion(const AssembledFrame& frame, const voxwall::Rect& region, int scale,
                            std::uint32_t fill, int threads) {
  if (scale < 1) throw std::invalid_argument("decodeRegion: scale must be at least 1");
  if (region.width <= 0 || region.height <= 0)
    throw std::invalid_argument("decodeRegion: empty region");
  voxwall::Image out((region.width + scale - 1) / scale, (region.height + scale - 1) / scale);
  std::fill(out.pixels.begin(), out.pixels.end(), fill);
  std::vector<Decoded> work;
  for (const auto& s : frame.segments) {
    const auto v = intersection(s.screen, region);
    if (v.width <= 0 || v.height <= 0) continue;
    int denominator = 1;
    if (s.codec == net::TileCodec::Jpeg)
      for (const int d : {8, 4, 2})
        if (d * frame.step <= scale) {
          denominator = d;
          break;
        }
    work.push_back({&s, denominator, {}});
  }
  voxwall::parallelFor(work.size(), threads, [&](std::size_t i) {
    const Segment& s = *work[i].segment;
    work[i].pixels = net::decodeTileScaled(
        *s.bytes, s.codec, s.rect.width, s.rect.height, work[i].denominator,
        "frame " + std::to_string(frame.frame) + ", a tile from rank " + std::to_string(s.rank));
  });
  for (const auto& d : work) paint(out, region, scale, frame.step, d);
  return out;
}

}  // namespace voxwall::walls
