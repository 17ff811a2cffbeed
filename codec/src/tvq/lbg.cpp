// LBG codebook training for the tvq codec (lbg.hpp).
#include "lbg.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec::tvq {

std::vector<std::uint32_t> nearestCodevectors(std::span<const float> vectors, int dims,
                                              std::span<const float> codebook, int threads,
                                              double* error2) {
  const std::size_t count = dims ? vectors.size() / std::size_t(dims) : 0;
  const std::size_t n = dims ? codebook.size() / std::size_t(dims) : 0;
  std::vector<std::uint32_t> out(count, 0);
  if (count == 0 || n <= 1) {
    if (error2) {
      double e = 0;
      for (std::size_t i = 0; i < count; ++i)
        for (int j = 0; j < dims; ++j) {
          const double d = double(vectors[i * std::size_t(dims) + std::size_t(j)]) -
                           (n ? double(codebook[std::size_t(j)]) : 0.0);
          e += d * d;
        }
      *error2 = e;
    }
    return out;
  }
  // |x - c|^2 = |x|^2 + |c|^2 - 2 c.x: the c.x of a chunk of vectors against every codevector is
  // one matrix product.
  const Eigen::Map<const Eigen::MatrixXf> c(codebook.data(), dims, Eigen::Index(n));
  const Eigen::VectorXf norms = c.colwise().squaredNorm().transpose();
  constexpr std::size_t kChunk = 256;
  const std::size_t chunks = (count + kChunk - 1) / kChunk;
  std::vector<double> errors(chunks, 0.0);
  parallelFor(chunks, threads, [&](std::size_t k) {
    const std::size_t first = k * kChunk, m = std::min(kChunk, count - first);
    const Eigen::Map<const Eigen::MatrixXf> x(vectors.data() + first * std::size_t(dims), dims,
                                              Eigen::Index(m));
    Eigen::MatrixXf dot = c.transpose() * x;  // n x m
    double e = 0;
    for (std::size_t j = 0; j < m; ++j) {
      float best = std::numeric_limits<float>::infinity();
      std::uint32_t at = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const float d = norms[Eigen::Index(i)] - 2.0f * dot(Eigen::Index(i), Eigen::Index(j));
        if (d < best) best = d, at = std::uint32_t(i);
      }
      out[first + j] = at;
      if (error2) {
        double s = 0;
        for (int t = 0; t < dims; ++t) {
          const double d = double(x(t, Eigen::Index(j))) - double(c(t, Eigen::Index(at)));
          s += d * d;
        }
        e += s;
      }
    }
    errors[k] = e;
  });
  if (error2) {
    double e = 0;
    for (double v : errors) e += v;
    *error2 = e;
  }
  return out;
}

namespace {

// One Lloyd update: centroids of the cells, per-dimension spread and distortion of each cell.
struct Cells {
  std::vector<double> sum, sum2, distortion;
  std::vector<std::uint64_t> members;
};

Cells cellsOf(std::span<const float> vectors, int dims, std::span<const float> codebook,
              const std::vector<std::uint32_t>& assignment) {
  const std::size_t n = codebook.size() / std::size_t(dims);
  Cells cells;
  cells.sum.assign(n * std::size_t(dims), 0.0);
  cells.sum2.assign(n * std::size_t(dims), 0.0);
  cells.distortion.assign(n, 0.0);
  cells.members.assign(n, 0);
  for (std::size_t i = 0; i < assignment.size(); ++i) {
    const std::size_t a = assignment[i];
    ++cells.members[a];
    for (int j = 0; j < dims; ++j) {
      const double v = vectors[i * std::size_t(dims) + std::size_t(j)];
      cells.sum[a * std::size_t(dims) + std::size_t(j)] += v;
      cells.sum2[a * std::size_t(dims) + std::size_t(j)] += v * v;
      const double d = v - double(codebook[a * std::size_t(dims) + std::size_t(j)]);
      cells.distortion[a] += d * d;
    }
  }
  return cells;
}

}  // namespace

std::vector<float> trainLbg(std::span<const float> vectors, int dims, std::size_t size,
                            int iterations, std::uint64_t seed, int threads) {
  const std::size_t count = vectors.size() / std::size_t(dims);
  if (count <= size) return {vectors.begin(), vectors.end()};
  std::mt19937_64 rng(seed);
  // The centroid.
  std::vector<float> codebook(std::size_t(dims), 0.0f);
  {
    std::vector<double> mean(std::size_t(dims), 0.0);
    for (std::size_t i = 0; i < count; ++i)
      for (int j = 0; j < dims; ++j)
        mean[std::size_t(j)] += vectors[i * std::size_t(dims) + std::size_t(j)];
    for (int j = 0; j < dims; ++j)
      codebook[std::size_t(j)] = float(mean[std::size_t(j)] / double(count));
  }
  std::vector<std::uint32_t> assignment(count, 0);
  Cells cells = cellsOf(vectors, dims, codebook, assignment);
  auto lloyd = [&](int rounds) {
    double last = std::numeric_limits<double>::infinity();
    for (int r = 0; r < rounds; ++r) {
      double error = 0;
      assignment = nearestCodevectors(vectors, dims, codebook, threads, &error);
      cells = cellsOf(vectors, dims, codebook, assignment);
      const std::size_t n = codebook.size() / std::size_t(dims);
      // Empty cells move to the worst-represented vectors (one each, never the same twice).
      std::vector<std::size_t> empty;
      for (std::size_t i = 0; i < n; ++i)
        if (cells.members[i] == 0) empty.push_back(i);
      if (!empty.empty()) {
        std::vector<std::pair<double, std::size_t>> worst;
        worst.reserve(count);
        for (std::size_t i = 0; i < count; ++i) {
          double s = 0;
          for (int j = 0; j < dims; ++j) {
            const double d = double(vectors[i * std::size_t(dims) + std::size_t(j)]) -
                             double(codebook[assignment[i] * std::size_t(dims) + std::size_t(j)]);
            s += d * d;
          }
          worst.push_back({s, i});
        }
        const std::size_t take = std::min(empty.size(), worst.size());
        std::partial_sort(worst.begin(), worst.begin() + std::ptrdiff_t(take), worst.end(),
                          [](const auto& a, const auto& b) { return a.first > b.first; });
        for (std::size_t e = 0; e < take; ++e)
          for (int j = 0; j < dims; ++j)
            codebook[empty[e] * std::size_t(dims) + std::size_t(j)] =
                vectors[worst[e].second * std::size_t(dims) + std::size_t(j)];
      }
      for (std::size_t i = 0; i < n; ++i) {
        if (cells.members[i] == 0) continue;
        for (int j = 0; j < dims; ++j)
          codebook[i * std::size_t(dims) + std::size_t(j)] =
              float(cells.sum[i * std::size_t(dims) + std::size_t(j)] / double(cells.members[i]));
      }
      if (empty.empty() && last - error <= 1e-5 * last) break;
      last = error;
    }
  };
  while (codebook.size() / std::size_t(dims) < size) {
    const std::size_t n = codebook.size() / std::size_t(dims);
    const std::size_t split = std::min(n, size - n);
    // Split the cells with the largest distortion.
    std::vector<std::size_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return cells.distortion[a] > cells.distortion[b];
    });
    std::uniform_int_distribution<int> coin(0, 1);
    for (std::size_t s = 0; s < split; ++s) {
      const std::size_t i = order[s];
      std::vector<float> twin(static_cast<std::size_t>(dims));
      for (int j = 0; j < dims; ++j) {
        const std::size_t at = i * std::size_t(dims) + std::size_t(j);
        const double m = cells.members[i] ? double(cells.members[i]) : 1.0;
        const double mean = cells.sum[at] / m;
        const double spread = std::sqrt(std::max(0.0, cells.sum2[at] / m - mean * mean));
        const double delta = 0.25 * (spread > 0 ? spread : 1e-3) * (coin(rng) ? 1.0 : -1.0);
        twin[std::size_t(j)] = float(double(codebook[at]) - delta);
        codebook[at] = float(double(codebook[at]) + delta);
      }
      codebook.insert(codebook.end(), twin.begin(), twin.end());
    }
    lloyd(codebook.size() / std::size_t(dims) < size ? 3 : std::max(1, iterations));
  }
  return codebook;
}

}  // namespace voxwall::codec::tvq
