// The measured cost of rendering, per cell of the virtual screen: the input of the load balancer.
#pragma once

#include <vector>
#include <voxwall/node/camera.hpp>

namespace voxwall::node {

// Seconds of work per square cell of `cellPixels` x `cellPixels` screen pixels (the cells at the
// right and bottom edges are clipped by the screen). A backend adds the time it spent on each
// pixel block while rendering; several ranks' grids add up to the cost of the whole frame.
struct CostGrid {
  int screenWidth = 0, screenHeight = 0;
  int cellPixels = 32;
  int cellsX = 0, cellsY = 0;
  std::vector<double> seconds;  // cellsX * cellsY, row-major, row 0 at the top

  CostGrid() = default;
  // Throws std::invalid_argument for a non-positive screen or cell size.
  CostGrid(int screenWidth, int screenHeight, int cellPixels);
  double& at(int cx, int cy) { return seconds[std::size_t(cy) * std::size_t(cellsX) + cx]; }
  double at(int cx, int cy) const { return seconds[std::size_t(cy) * std::size_t(cellsX) + cx]; }
  // The screen pixels of cell (cx, cy).
  Rect cellRect(int cx, int cy) const;
  // Spreads `cost` over the cells `rect` overlaps, in proportion to the pixels in each.
  void add(const Rect& rect, double cost);
  // The cost inside `rect`, counting a partly covered cell by the share of its pixels inside.
  double costOf(const Rect& rect) const;
  double total() const;
  void clear();
};

}  // namespace voxwall::node
