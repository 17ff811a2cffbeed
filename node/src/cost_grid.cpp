#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>
#include <voxwall/node/cost_grid.hpp>

namespace voxwall::node {

CostGrid::CostGrid(int width, int height, int cell)
    : screenWidth(width), screenHeight(height), cellPixels(cell) {
  if (width <= 0 || height <= 0 || cell <= 0)
    throw std::invalid_argument("cost grid: screen " + std::to_string(width) + "x" +
                                std::to_string(height) + " with " + std::to_string(cell) +
                                "-pixel cells");
  cellsX = (width + cell - 1) / cell;
  cellsY = (height + cell - 1) / cell;
  seconds.assign(std::size_t(cellsX) * std::size_t(cellsY), 0.0);
}

Rect CostGrid::cellRect(int cx, int cy) const {
  const int x0 = cx * cellPixels, y0 = cy * cellPixels;
  return {x0, y0, std::min(cellPixels, screenWidth - x0), std::min(cellPixels, screenHeight - y0)};
}

namespace {

// Calls f(cx, cy, overlapPixels) for every cell that `rect` overlaps (rect clipped to the screen).
template <typename F>
void forCells(const CostGrid& g, const Rect& rect, F&& f) {
  const int x0 = std::max(rect.x, 0), y0 = std::max(rect.y, 0);
  const int x1 = std::min(rect.x + rect.width, g.screenWidth);
  const int y1 = std::min(rect.y + rect.height, g.screenHeight);
  if (x0 >= x1 || y0 >= y1) return;
  for (int cy = y0 / g.cellPixels; cy <= (y1 - 1) / g.cellPixels; ++cy) {
    const int cy0 = std::max(y0, cy * g.cellPixels), cy1 = std::min(y1, (cy + 1) * g.cellPixels);
    for (int cx = x0 / g.cellPixels; cx <= (x1 - 1) / g.cellPixels; ++cx) {
      const int cx0 = std::max(x0, cx * g.cellPixels);
      const int cx1 = std::min(x1, (cx + 1) * g.cellPixels);
      f(cx, cy, double(cx1 - cx0) * double(cy1 - cy0));
    }
  }
}

}  // namespace

void CostGrid::add(const Rect& rect, double cost) {
  const double area = double(rect.area());
  if (area <= 0) return;
  forCells(*this, rect, [&](int cx, int cy, double pixels) { at(cx, cy) += cost * pixels / area; });
}

double CostGrid::costOf(const Rect& rect) const {
  double sum = 0;
  forCells(*this, rect, [&](int cx, int cy, double pixels) {
    sum += at(cx, cy) * pixels / double(cellRect(cx, cy).area());
  });
  return sum;
}

double CostGrid::total() const { return std::accumulate(seconds.begin(), seconds.end(), 0.0); }

void CostGrid::clear() { std::fill(seconds.begin(), seconds.end(), 0.0); }

}  // namespace voxwall::node
