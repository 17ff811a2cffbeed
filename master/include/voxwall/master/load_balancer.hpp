// Cutting the virtual screen among the rendering ranks (sort-first), statically or from the
// costs measured in the previous frame (dynamic), like Equalizer's 2D load balancer.
#pragma once

#include <span>
#include <vector>
#include <voxwall/node/cost_grid.hpp>

namespace voxwall::master {

// `count` horizontal strips of equal area (heights differ by at most one pixel).
// Throws std::invalid_argument when count < 1 or count > height.
std::vector<voxwall::Rect> stripCut(int width, int height, int count);

// Grid of tiles covering a width x height screen exactly (rows and columns differ by at most
// one pixel), row by row. Throws std::invalid_argument for counts < 1 or larger than the screen.
std::vector<voxwall::Rect> gridCut(int width, int height, int tilesX, int tilesY);

// Recursive bisection of `screen` into `count` rectangles of equal cost under `costs` (cost
// spread evenly inside each cell). Splits the longer side first, at pixel precision; every
// rectangle is at least one pixel. Zero, negative or non-finite cells count as free; a grid with
// no usable cost cuts by area. The result tiles `screen` exactly. Throws std::invalid_argument
// when `screen` has fewer pixels than `count`.
std::vector<voxwall::Rect> bisectCut(const node::CostGrid& costs, const voxwall::Rect& screen,
                                     int count);

// max / mean of `costs` (1 = perfect balance; 1 for an empty or all-zero list).
double imbalance(const std::vector<double>& costs);

struct BalancerSettings {
  int cellPixels = 32;       // cost grid cell
  double smoothing = 0.5;    // weight of the newest frame in the cost prediction
  double recutAbove = 1.05;  // keep the current cut while it predicts at most this
  double resetAbove = 1.30;  // a frame this unbalanced replaces the prediction outright
  double minGain = 0.02;     // a new cut must predict at least this much less imbalance
};

// The dynamic balancer. Not thread-safe.
//
// Damping (so a still camera settles instead of jittering): the prediction is an exponential
// average of the measured cost grids, and the cut only changes when the current cut, judged by
// the prediction, is more than `recutAbove` out of balance. A sudden change of view (a measured
// imbalance above `resetAbove`) replaces the prediction with the newest frame, so the cut follows
// within a frame or two.
class LoadBalancer {
 public:
  // Throws std::invalid_argument for fewer than one rank or a screen smaller than the ranks.
  LoadBalancer(int width, int height, int ranks, BalancerSettings settings = {});

  // One rectangle per rendering slot for the next frame (equal-area strips before any costs).
  const std::vector<voxwall::Rect>& cut() const { return cut_; }

  // Feeds the frame rendered with cut(): each slot's measured cost grid (only the cells its
  // rectangle covers are read; an empty grid means "not measured") and its wall time. The cells
  // are scaled so they add up to the wall time. Absurd numbers are repaired, never trusted: a
  // time that is negative, not finite or over a day becomes the others' mean; a grid with
  // negative or non-finite cells, or none, is replaced by the time spread over the rectangle.
  // Then re-cuts if the damping rules say so. Throws std::invalid_argument on a size mismatch.
  void update(const std::vector<node::CostGrid>& slotGrids, std::vector<double> slotSeconds);

  // The current cut's imbalance as the prediction sees it; the number of re-cuts so far.
  double predictedImbalance() const;
  int recuts() const { return recuts_; }

 private:
  int width_, height_, ranks_;
  BalancerSettings settings_;
  std::vector<voxwall::Rect> cut_;
  node::CostGrid prediction_;
  bool havePrediction_ = false;
  int recuts_ = 0;
};

}  // namespace voxwall::master
