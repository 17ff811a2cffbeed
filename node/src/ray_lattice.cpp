#include <algorithm>
#include <bit>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <stdexcept>
#include <voxwall/core/parallel.hpp>
#include <voxwall/node/ray_lattice.hpp>

namespace voxwall::node {

TileStats Backend::render(const RenderVolume& volume, const FramePlan& plan, const Rect& tile,
                          Image& out, CostGrid* costs, const std::atomic<bool>* stop) {
  if (plan.latticeStride > 1 && tracesLattices())
    return renderLattice(*this, volume, plan, tile, out, costs, stop);
  TileStats stats = renderTile(volume, plan, tile, out, costs, stop);
  if (stats.rays == 0 && !stats.stopped) stats.rays = std::uint64_t(tile.area());
  return stats;
}

TileStats Backend::renderPoints(const RenderVolume&, const FramePlan&, const RayPoints&, Image&,
                                CostGrid*, const std::atomic<bool>*) {
  throw std::logic_error(name() + " does not trace ray lattices");
}

int autoLatticeStride(const codec::VolumeInfo& info, const Camera& camera, int screenHeight) {
  const glm::dvec3 half = glm::dvec3(info.dims) * info.spacing * 0.5;
  // The volume's box is centred on the origin of patient space: its farthest corner from the eye.
  double farthest = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::dvec3 sign((corner & 1) ? 1 : -1, (corner & 2) ? 1 : -1, (corner & 4) ? 1 : -1);
    farthest =
        std::max(farthest, glm::length(info.orientation.direction * (sign * half) - camera.eye));
  }
  const double minSpacing = std::min({info.spacing.x, info.spacing.y, info.spacing.z});
  const double pixelAngle =
      2.0 * std::tan(camera.fovYDeg * std::numbers::pi / 360.0) / double(screenHeight);
  if (!(farthest > 0) || !(pixelAngle > 0)) return 1;
  const double voxelPixels = minSpacing / (farthest * pixelAngle);
  int stride = 1;
  while (stride * 2 <= kMaxLatticeStride && double(stride * 2) <= voxelPixels / 2.0) stride *= 2;
  return stride;
}

int cornerSpread(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
  int spread = 0;
  for (int shift = 0; shift < 32; shift += 8) {
    const int va = int((a >> shift) & 255u), vb = int((b >> shift) & 255u);
    const int vc = int((c >> shift) & 255u), vd = int((d >> shift) & 255u);
    spread = std::max(spread, std::max({va, vb, vc, vd}) - std::min({va, vb, vc, vd}));
  }
  return spread;
}

std::uint32_t blendCorners(std::uint32_t c00, std::uint32_t c10, std::uint32_t c01,
                           std::uint32_t c11, int s, int fx, int fy) {
  const std::uint32_t w00 = std::uint32_t((s - fx) * (s - fy)), w10 = std::uint32_t(fx * (s - fy));
  const std::uint32_t w01 = std::uint32_t((s - fx) * fy), w11 = std::uint32_t(fx * fy);
  const std::uint32_t total = std::uint32_t(s * s);
  // A lattice's side is a power of two: the division is a shift (the same value).
  const bool power = (s & (s - 1)) == 0;
  const int log2Total = 2 * std::countr_zero(std::uint32_t(s));
  std::uint32_t out = 0;
  for (int shift = 0; shift < 32; shift += 8) {
    const std::uint32_t sum = ((c00 >> shift) & 255u) * w00 + ((c10 >> shift) & 255u) * w10 +
                              ((c01 >> shift) & 255u) * w01 + ((c11 >> shift) & 255u) * w11;
    const std::uint32_t v = power ? (sum + total / 2) >> log2Total : (sum + total / 2) / total;
    out |= v << shift;
  }
  return out;
}

namespace {

// The lattice over one tile: the cells of the top stride that cover it, and the rays cast so far
// at every pixel of their union (corners included), in region-local pixel coordinates.
class TileLattice {
 public:
  TileLattice(const Rect& tile, int stride) : tile_(tile), top_(stride) {
    const int cx0 = tile.x / stride, cy0 = tile.y / stride;
    const int cx1 = (tile.x + tile.width - 1) / stride, cy1 = (tile.y + tile.height - 1) / stride;
    x0_ = cx0 * stride, y0_ = cy0 * stride;
    width_ = (cx1 - cx0 + 1) * stride + 1, height_ = (cy1 - cy0 + 1) * stride + 1;
    rays_.assign(std::size_t(width_) * std::size_t(height_), 0u);
    cast_.assign(rays_.size(), 0);
    for (int y = 0; y + stride < height_; y += stride)
      for (int x = 0; x + stride < width_; x += stride) cells_.push_back({x, y});
  }

  struct Cell {
    int x, y;  // its top-left corner, region-local
  };

  // Casts the corner rays of the current cells (of side s) not cast yet.
  TileStats castLevel(Backend& backend, const RenderVolume& volume, const FramePlan& plan, int s,
                      CostGrid* costs, const std::atomic<bool>* stop) {
    const int nx = (width_ - 1) / s + 1, ny = (height_ - 1) / s + 1;
    // The points to cast, and their bounding box in lattice indices.
    std::vector<std::uint8_t> want(std::size_t(nx) * std::size_t(ny), 0);
    int ix0 = nx, iy0 = ny, ix1 = -1, iy1 = -1;
    auto mark = [&](int x, int y) {
      if (cast_[index(x, y)]) return;
      const int ix = x / s, iy = y / s;
      want[std::size_t(iy) * std::size_t(nx) + std::size_t(ix)] = 1;
      ix0 = std::min(ix0, ix), iy0 = std::min(iy0, iy);
      ix1 = std::max(ix1, ix), iy1 = std::max(iy1, iy);
    };
    for (const Cell& c : cells_)  // cells of side s: their four corners
      for (int b = 0; b <= s; b += s)
        for (int a = 0; a <= s; a += s) mark(c.x + a, c.y + b);
    TileStats stats;
    if (ix1 < 0) return stats;
    const int bw = ix1 - ix0 + 1, bh = iy1 - iy0 + 1;
    std::vector<std::uint8_t> need(std::size_t(bw) * std::size_t(bh));
    for (int iy = 0; iy < bh; ++iy)
      std::copy_n(want.begin() + std::ptrdiff_t((iy0 + iy) * nx + ix0), bw,
                  need.begin() + std::ptrdiff_t(iy * bw));
    Image points(bw, bh);
    stats = backend.renderPoints(volume, plan,
                                 RayPoints{{x0_ + ix0 * s, y0_ + iy0 * s, bw, bh}, s, need.data()},
                                 points, costs, stop);
    for (int iy = 0; iy < bh; ++iy)
      for (int ix = 0; ix < bw; ++ix)
        if (need[std::size_t(iy) * std::size_t(bw) + std::size_t(ix)]) {
          const std::size_t i = index((ix0 + ix) * s, (iy0 + iy) * s);
          rays_[i] = points.at(ix, iy);
          cast_[i] = 1;
        }
    return stats;
  }

  // Cells of side s: those whose corners span more than `threshold` become their four children
  // that cover part of the tile (side s / 2); the others are filled into `out` and dropped. On
  // `threads` threads, a run of cells each (cells write disjoint pixels).
  void splitOrFill(int s, int threshold, Image& out, int threads) {
    std::vector<std::uint8_t> split(cells_.size(), 0);
    constexpr std::size_t kRun = 4096;
    voxwall::parallelFor((cells_.size() + kRun - 1) / kRun, threads, [&](std::size_t run) {
      const std::size_t end = std::min(cells_.size(), (run + 1) * kRun);
      for (std::size_t i = run * kRun; i < end; ++i) {
        const Cell& c = cells_[i];
        const std::uint32_t c00 = ray(c.x, c.y), c10 = ray(c.x + s, c.y);
        const std::uint32_t c01 = ray(c.x, c.y + s), c11 = ray(c.x + s, c.y + s);
        if (s > 1 && cornerSpread(c00, c10, c01, c11) > threshold) {
          split[i] = 1;
          continue;
        }
        fill(c, s, c00, c10, c01, c11, out);
      }
    });
    std::vector<Cell> next;
    const int h = s / 2;
    for (std::size_t i = 0; i < cells_.size(); ++i) {
      if (!split[i]) continue;
      const Cell& c = cells_[i];
      for (int b = 0; b < 2; ++b)
        for (int a = 0; a < 2; ++a)
          if (covers({c.x + a * h, c.y + b * h}, h)) next.push_back({c.x + a * h, c.y + b * h});
    }
    cells_ = std::move(next);
  }

  // The cell's pixels inside the tile, from its corners.
  void fill(const Cell& c, int s, std::uint32_t c00, std::uint32_t c10, std::uint32_t c01,
            std::uint32_t c11, Image& out) const {
    const int px0 = std::max(x0_ + c.x, tile_.x), py0 = std::max(y0_ + c.y, tile_.y);
    const int px1 = std::min(x0_ + c.x + s, tile_.x + tile_.width);
    const int py1 = std::min(y0_ + c.y + s, tile_.y + tile_.height);
    if (c00 == c10 && c00 == c01 && c00 == c11) {  // flat (the background, mostly)
      for (int y = py0; y < py1; ++y)
        std::fill_n(&out.at(px0 - tile_.x, y - tile_.y), px1 - px0, c00);
      return;
    }
    for (int y = py0; y < py1; ++y)
      for (int x = px0; x < px1; ++x)
        out.at(x - tile_.x, y - tile_.y) =
            blendCorners(c00, c10, c01, c11, s, x - x0_ - c.x, y - y0_ - c.y);
  }

  bool done() const { return cells_.empty(); }

 private:
  std::size_t index(int x, int y) const {
    return std::size_t(y) * std::size_t(width_) + std::size_t(x);
  }
  std::uint32_t ray(int x, int y) const { return rays_[index(x, y)]; }
  // Does the cell of side s at c hold a pixel of the tile?
  bool covers(const Cell& c, int s) const {
    return x0_ + c.x < tile_.x + tile_.width && x0_ + c.x + s > tile_.x &&
           y0_ + c.y < tile_.y + tile_.height && y0_ + c.y + s > tile_.y;
  }

  Rect tile_;
  int top_;
  int x0_ = 0, y0_ = 0, width_ = 0, height_ = 0;  // the region: pixels [x0, x0 + width) ...
  std::vector<std::uint32_t> rays_;
  std::vector<std::uint8_t> cast_;
  std::vector<Cell> cells_;  // the cells of the current side still to decide
};

}  // namespace

TileStats renderLattice(Backend& backend, const RenderVolume& volume, const FramePlan& plan,
                        const Rect& tile, Image& out, CostGrid* costs,
                        const std::atomic<bool>* stop) {
  if (tile.width <= 0 || tile.height <= 0) throw std::invalid_argument("empty tile");
  const int top = plan.latticeStride;
  if (top < 1 || top > kMaxLatticeStride || (top & (top - 1)) != 0)
    throw std::invalid_argument("ray lattice stride must be a power of two up to " +
                                std::to_string(kMaxLatticeStride));
  out = Image(tile.width, tile.height);
  TileLattice lattice(tile, top);
  TileStats stats;
  for (int s = top; s >= 1 && !lattice.done(); s /= 2) {
    const TileStats level = lattice.castLevel(backend, volume, plan, s, costs, stop);
    stats.samples += level.samples;
    stats.rays += level.rays;
    stats.pageHits += level.pageHits, stats.pageMissed += level.pageMissed;
    stats.pageDecoded += level.pageDecoded, stats.pageEvictions += level.pageEvictions;
    stats.pageCoarse += level.pageCoarse;
    stats.pageResidentBytes = level.pageResidentBytes;
    stats.seconds += level.seconds;
    if (level.stopped || (stop && stop->load())) {
      stats.stopped = true;
      return stats;
    }
    lattice.splitOrFill(s, plan.refineAboveLevels, out, backend.hostThreads());
  }
  return stats;
}

}  // namespace voxwall::node
