// Weighted k-means over 4^3 bricks for the VQ codec (Guthe & Goesele, section 4): furthest-first
// initialisation with a lazy priority queue (Algorithm 2), the distance with the norm-difference
// bound (Algorithm 1), and the changed/unchanged-centre bookkeeping (Algorithms 3-4) that
// computes only the distances that can change an assignment.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::vq {

inline constexpr int kDims = 64;
using Point = std::array<std::uint16_t, kDims>;

struct KMeansResult {
  std::vector<std::array<double, kDims>> centers;  // k centres (weighted means)
  std::vector<std::uint32_t> assignment;           // centre of each point
  int iterations = 0;                              // centre updates done
  bool converged = false;                          // no centre moved in the last update
  // Distances: computed in full, skipped by the norm bound (Algorithm 1), and the number a
  // plain implementation (furthest-first by brute force, then Lloyd) would have computed.
  std::uint64_t computed = 0, skipped = 0, plainEquivalent = 0;
};

// Clusters `points` (weights: how often each occurs, > 0) into min(k, points) centres.
// Deterministic for any thread count. Ties between equal distances keep the earlier centre.
KMeansResult kmeans(std::span<const Point> points, std::span<const std::uint32_t> weights,
                    std::size_t k, int maxIterations, int threads, Progress& progress);

// The same clustering with no pruning: furthest-first by brute force, then Lloyd iterations
// checking every centre. The reference for tests and the speed-up measurement.
KMeansResult kmeansBruteForce(std::span<const Point> points, std::span<const std::uint32_t> weights,
                              std::size_t k, int maxIterations);

}  // namespace voxwall::codec::vq
