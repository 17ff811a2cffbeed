#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>
#include <voxwall/master/load_balancer.hpp>

namespace voxwall::master {

using node::CostGrid;
using voxwall::Rect;

std::vector<Rect> stripCut(int width, int height, int count) {
  if (count < 1 || count > height || width < 1)
    throw std::invalid_argument("cannot cut a " + std::to_string(width) + "x" +
                                std::to_string(height) + " screen into " + std::to_string(count) +
                                " strips");
  std::vector<Rect> strips;
  for (int i = 0; i < count; ++i) {
    const int y0 = int((long long)height * i / count),
              y1 = int((long long)height * (i + 1) / count);
    strips.push_back({0, y0, width, y1 - y0});
  }
  return strips;
}

std::vector<Rect> gridCut(int width, int height, int tilesX, int tilesY) {
  if (tilesX < 1 || tilesY < 1 || tilesX > width || tilesY > height)
    throw std::invalid_argument("tile grid " + std::to_string(tilesX) + "x" +
                                std::to_string(tilesY) + " does not fit a " +
                                std::to_string(width) + "x" + std::to_string(height) + " screen");
  std::vector<Rect> tiles;
  for (int j = 0; j < tilesY; ++j)
    for (int i = 0; i < tilesX; ++i) {
      const int x0 = int((long long)width * i / tilesX),
                x1 = int((long long)width * (i + 1) / tilesX);
      const int y0 = int((long long)height * j / tilesY),
                y1 = int((long long)height * (j + 1) / tilesY);
      tiles.push_back({x0, y0, x1 - x0, y1 - y0});
    }
  return tiles;
}

double imbalance(const std::vector<double>& costs) {
  if (costs.empty()) return 1.0;
  const double mean = std::accumulate(costs.begin(), costs.end(), 0.0) / double(costs.size());
  const double max = *std::max_element(costs.begin(), costs.end());
  return mean > 0 ? max / mean : 1.0;
}

namespace {

bool usable(double v) { return std::isfinite(v) && v >= 0; }

// Cost of every pixel line across `rect` along one axis: columns (splitX) or rows.
std::vector<double> lineCosts(const CostGrid& g, const Rect& rect, bool splitX, double floorCost) {
  const int length = splitX ? rect.width : rect.height;
  std::vector<double> lines(std::size_t(length), 0.0);
  const int across0 = splitX ? rect.y : rect.x;
  const int across1 = across0 + (splitX ? rect.height : rect.width);
  const double acrossPixels = double(across1 - across0);
  for (int i = 0; i < length; ++i) {
    const int p = (splitX ? rect.x : rect.y) + i;
    double sum = 0;
    if (g.cellsX > 0) {
      const int c = p / g.cellPixels;
      for (int k = across0 / g.cellPixels; k <= (across1 - 1) / g.cellPixels; ++k) {
        const int cx = splitX ? c : k, cy = splitX ? k : c;
        const double v = g.at(cx, cy);
        if (!usable(v)) continue;
        const Rect cell = g.cellRect(cx, cy);
        const int a0 = std::max(across0, k * g.cellPixels);
        const int a1 = std::min(across1, k * g.cellPixels + g.cellPixels);
        sum += v * double(a1 - a0) / double(cell.area());
      }
    }
    lines[std::size_t(i)] = sum + floorCost * acrossPixels;
  }
  return lines;
}

void bisect(const CostGrid& g, const Rect& rect, int count, double floorCost,
            std::vector<Rect>& out) {
  if (count == 1) {
    out.push_back(rect);
    return;
  }
  int n1 = count / 2;
  // Split the longer side; fall back to the other when one-pixel minimums do not fit.
  bool splitX = rect.width >= rect.height;
  auto bounds = [&](bool alongX, int first) {
    const int length = alongX ? rect.width : rect.height,
              across = alongX ? rect.height : rect.width;
    const int lo = (first + across - 1) / across;
    const int hi = length - (count - first + across - 1) / across;
    return std::pair{lo, hi};
  };
  auto [lo, hi] = bounds(splitX, n1);
  if (lo > hi || lo < 1) {
    splitX = !splitX;
    std::tie(lo, hi) = bounds(splitX, n1);
  }
  if (lo > hi || lo < 1) {
    // Degenerate (as many ranks as pixels): split the longer side in half and the ranks by area.
    splitX = rect.width >= rect.height;
    const int length = splitX ? rect.width : rect.height,
              across = splitX ? rect.height : rect.width;
    lo = hi = length / 2;
    n1 = std::clamp(count - (length - lo) * across, 1, std::min(lo * across, count - 1));
  }
  const auto lines = lineCosts(g, rect, splitX, floorCost);
  const double total = std::accumulate(lines.begin(), lines.end(), 0.0);
  const double target = total * double(n1) / double(count);
  int best = lo;
  double bestErr = INFINITY, prefix = 0;
  for (int s = 1; s <= hi; ++s) {
    prefix += lines[std::size_t(s - 1)];
    if (s < lo) continue;
    const double err = std::abs(prefix - target);
    if (err < bestErr) bestErr = err, best = s;
    if (prefix > target) break;
  }
  Rect a = rect, b = rect;
  if (splitX) {
    a.width = best;
    b.x += best, b.width -= best;
  } else {
    a.height = best;
    b.y += best, b.height -= best;
  }
  bisect(g, a, n1, floorCost, out);
  bisect(g, b, count - n1, floorCost, out);
}

// The frame's measured cost grid (`measured`, empty, of the screen): each slot's cells scaled so
// that they sum to its seconds; a slot whose grid cannot be trusted (another grid, a cell not a
// finite non-negative time, nothing measured) spreads its seconds evenly over its rectangle.
CostGrid measuredCosts(CostGrid measured, const std::vector<Rect>& cut,
                       const std::vector<CostGrid>& slotGrids,
                       const std::vector<double>& slotSeconds) {
  for (std::size_t i = 0; i < cut.size(); ++i) {
    const Rect& rect = cut[i];
    const CostGrid& g = slotGrids[i];
    const bool sameGrid = g.cellsX == measured.cellsX && g.cellsY == measured.cellsY &&
                          g.cellPixels == measured.cellPixels;
    // The slot's own cells: those its rectangle overlaps.
    const int cx0 = rect.x / measured.cellPixels,
              cx1 = (rect.x + rect.width - 1) / measured.cellPixels;
    const int cy0 = rect.y / measured.cellPixels,
              cy1 = (rect.y + rect.height - 1) / measured.cellPixels;
    double sum = 0;
    bool sane = sameGrid;
    for (int cy = cy0; sane && cy <= cy1; ++cy)
      for (int cx = cx0; sane && cx <= cx1; ++cx) {
        const double v = g.at(cx, cy);
        if (!usable(v)) sane = false;
        sum += v;
      }
    if (!sane || !(sum > 0) || !std::isfinite(sum)) {
      measured.add(rect, slotSeconds[i]);
      continue;
    }
    const double scale = slotSeconds[i] / sum;
    for (int cy = cy0; cy <= cy1; ++cy)
      for (int cx = cx0; cx <= cx1; ++cx) measured.at(cx, cy) += g.at(cx, cy) * scale;
  }
  return measured;
}

}  // namespace

std::vector<Rect> bisectCut(const CostGrid& costs, const Rect& screen, int count) {
  if (count < 1 || screen.width < 1 || screen.height < 1 || screen.area() < count)
    throw std::invalid_argument("cannot cut a " + std::to_string(screen.width) + "x" +
                                std::to_string(screen.height) + " screen into " +
                                std::to_string(count) + " rectangles");
  double total = 0;
  for (double v : costs.seconds)
    if (usable(v)) total += v;
  // Empty pixels still cost a little (ray setup); with no usable cost at all, cut by area.
  const double pixels = double(costs.screenWidth) * double(costs.screenHeight);
  const double floorCost = total > 0 && pixels > 0 ? 1e-3 * total / pixels : 1.0;
  std::vector<Rect> out;
  out.reserve(std::size_t(count));
  bisect(total > 0 ? costs : CostGrid{}, screen, count, floorCost, out);
  return out;
}

LoadBalancer::LoadBalancer(int width, int height, int ranks, BalancerSettings settings)
    : width_(width), height_(height), ranks_(ranks), settings_(settings) {
  if (ranks < 1) throw std::invalid_argument("load balancer: no rendering ranks");
  if (ranks > height)
    throw std::invalid_argument(std::to_string(ranks) + " rendering ranks for a screen " +
                                std::to_string(height) + " pixels high");
  cut_ = stripCut(width, height, ranks);
  prediction_ = CostGrid(width, height, settings.cellPixels);
}

double LoadBalancer::predictedImbalance() const {
  if (!havePrediction_) return 1.0;
  std::vector<double> costs;
  for (const auto& r : cut_) costs.push_back(prediction_.costOf(r));
  return imbalance(costs);
}

void LoadBalancer::update(const std::vector<CostGrid>& slotGrids, std::vector<double> slotSeconds) {
  if (slotGrids.size() != std::size_t(ranks_) || slotSeconds.size() != std::size_t(ranks_))
    throw std::invalid_argument("load balancer: " + std::to_string(slotGrids.size()) +
                                " grids and " + std::to_string(slotSeconds.size()) + " times for " +
                                std::to_string(ranks_) + " ranks");
  constexpr double kDaySeconds = 86400;
  double validSum = 0;
  int valid = 0;
  for (double s : slotSeconds)
    if (usable(s) && s <= kDaySeconds) validSum += s, ++valid;
  const double fallback = valid > 0 ? validSum / valid : 1.0;
  for (double& s : slotSeconds)
    if (!usable(s) || s > kDaySeconds) s = fallback;

  const CostGrid measured =
      measuredCosts(CostGrid(width_, height_, settings_.cellPixels), cut_, slotGrids, slotSeconds);

  if (!havePrediction_ || imbalance(slotSeconds) > settings_.resetAbove) {
    prediction_ = measured;
  } else {
    const double a = settings_.smoothing;
    for (std::size_t k = 0; k < prediction_.seconds.size(); ++k)
      prediction_.seconds[k] = a * measured.seconds[k] + (1 - a) * prediction_.seconds[k];
  }
  havePrediction_ = true;

  const double current = predictedImbalance();
  if (current <= settings_.recutAbove) return;
  auto candidate = bisectCut(prediction_, {0, 0, width_, height_}, ranks_);
  std::vector<double> costs;
  for (const auto& r : candidate) costs.push_back(prediction_.costOf(r));
  if (imbalance(costs) < current - settings_.minGain) {
    cut_ = std::move(candidate);
    ++recuts_;
  }
}

}  // namespace voxwall::master
