// The ksvd codec's learning half: orthogonal matching pursuit, the coreset and K-SVD
// (ksvd_codec.hpp; docs/ksvd.md explains each step).
#include "learning.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>
#include <voxwall/core/parallel.hpp>

#include "format.hpp"

namespace voxwall::codec::ksvd {

// ---- OMP --------------------------------------------------------------------------------

Coder::Coder(const Dictionary& d) : m_(d.m), k_(d.atoms) {
  atoms_ = Eigen::Map<const Eigen::MatrixXf>(d.values.data(), d.m, d.atoms);
  gram_ = atoms_.transpose() * atoms_;
}

void Coder::correlate(const float* blocks, std::size_t count, Eigen::MatrixXf& alpha) const {
  const Eigen::Map<const Eigen::MatrixXf> y(blocks, m_, Eigen::Index(count));
  alpha.noalias() = atoms_.transpose() * y;
}

void Coder::code(const float* alpha0, double energy, int sparsity, double maxResidual2,
                 SparseCode& out, Work& w, double minGain2) const {
  const int s = std::max(1, std::min(sparsity, k_));
  out.atoms.clear(), out.coefficients.clear();
  w.lower.assign(std::size_t(s) * std::size_t(s), 0.0);
  w.alpha.resize(std::size_t(k_));
  w.chosen.assign(std::size_t(k_), 0);
  std::vector<int>& idx = out.atoms;
  std::vector<double>& gamma = w.gamma;
  std::vector<double>& rhs = w.rhs;
  auto L = [&](int r, int c) -> double& { return w.lower[std::size_t(r) * std::size_t(s) + c]; };
  // The DC atom first.
  idx.push_back(0);
  w.chosen[0] = 1;
  L(0, 0) = std::sqrt(std::max(double(gram_(0, 0)), 1e-12));
  double residual2 = energy;
  for (;;) {
    const int k = int(idx.size());
    // gamma = (G_II)^-1 alpha0_I through the Cholesky factor L L^T.
    rhs.resize(std::size_t(k)), gamma.resize(std::size_t(k));
    for (int i = 0; i < k; ++i) {
      double v = alpha0[idx[std::size_t(i)]];
      for (int j = 0; j < i; ++j) v -= L(i, j) * rhs[std::size_t(j)];
      rhs[std::size_t(i)] = v / L(i, i);
    }
    for (int i = k - 1; i >= 0; --i) {
      double v = rhs[std::size_t(i)];
      for (int j = i + 1; j < k; ++j) v -= L(j, i) * gamma[std::size_t(j)];
      gamma[std::size_t(i)] = v / L(i, i);
    }
    double explained = 0;
    for (int i = 0; i < k; ++i) explained += gamma[std::size_t(i)] * alpha0[idx[std::size_t(i)]];
    residual2 = std::max(0.0, energy - explained);
    if (k >= s || residual2 <= maxResidual2) break;
    // alpha = alpha0 - G_I gamma: the residual's correlation with every atom.
    for (int a = 0; a < k_; ++a) w.alpha[std::size_t(a)] = alpha0[a];
    for (int i = 0; i < k; ++i) {
      const float g = float(gamma[std::size_t(i)]);
      const float* col = gram_.data() + std::size_t(idx[std::size_t(i)]) * std::size_t(k_);
      for (int a = 0; a < k_; ++a) w.alpha[std::size_t(a)] -= g * col[a];
    }
    int best = -1;
    float bestValue = 0;
    for (int a = 0; a < k_; ++a) {
      const float v = std::abs(w.alpha[std::size_t(a)]);
      if (!w.chosen[std::size_t(a)] && v > bestValue) bestValue = v, best = a;
    }
    if (best < 0 || double(bestValue) * double(bestValue) <= 1e-14 * std::max(energy, 1e-30)) break;
    // Extend the factor: L w = G_I,best; the new diagonal sqrt(G_bb - w.w).
    double norm2 = 0;
    for (int i = 0; i < k; ++i) {
      double v = gram_(idx[std::size_t(i)], best);
      for (int j = 0; j < i; ++j) v -= L(i, j) * L(k, j);
      L(k, i) = v / L(i, i);
      norm2 += L(k, i) * L(k, i);
    }
    const double diag2 = double(gram_(best, best)) - norm2;
    // Adding `best` takes alpha_best^2 / diag2 off the squared residual (its correlation with
    // the residual over the norm of its part orthogonal to the chosen atoms, squared).
    if (diag2 <= 1e-6 || double(bestValue) * double(bestValue) < minGain2 * diag2) {
      // nearly a combination of the chosen atoms, or worth less than a pair costs
      for (int i = 0; i < k; ++i) L(k, i) = 0;
      break;
    }
    L(k, k) = std::sqrt(diag2);
    idx.push_back(best);
    w.chosen[std::size_t(best)] = 1;
  }
  out.coefficients.resize(idx.size());
  for (std::size_t i = 0; i < idx.size(); ++i) out.coefficients[i] = float(gamma[i]);
  out.residual2 = residual2;
}

SparseCode ompCode(const Dictionary& dictionary, std::span<const float> y, int sparsity,
                   double maxResidual2) {
  if (int(y.size()) != dictionary.m) throw std::invalid_argument("ompCode: block size mismatch");
  const Coder coder(dictionary);
  Eigen::MatrixXf alpha;
  coder.correlate(y.data(), 1, alpha);
  double energy = 0;
  for (float v : y) energy += double(v) * double(v);
  SparseCode code;
  Coder::Work work;
  coder.code(alpha.data(), energy, sparsity, maxResidual2, code, work);
  return code;
}

void codeAll(const Coder& coder, const float* blocks, std::size_t count, int sparsity,
             double maxResidual2, int threads, std::vector<SparseCode>& codes,
             const std::function<void(std::size_t)>& advance, double minGain2) {
  constexpr std::size_t kChunk = 128;
  codes.resize(count);
  const int m = coder.m();
  parallelFor((count + kChunk - 1) / kChunk, threads, [&](std::size_t c) {
    const std::size_t first = c * kChunk, n = std::min(kChunk, count - first);
    const float* y = blocks + first * std::size_t(m);
    Eigen::MatrixXf alpha;
    coder.correlate(y, n, alpha);
    Coder::Work work;
    for (std::size_t i = 0; i < n; ++i) {
      double energy = 0;
      for (int v = 0; v < m; ++v) energy += double(y[i * m + v]) * double(y[i * m + v]);
      coder.code(alpha.data() + i * std::size_t(coder.atoms()), energy, sparsity, maxResidual2,
                 codes[first + i], work, minGain2);
    }
    if (advance) advance(n);
  });
}

// ---- the coreset --------------------------------------------------------------------------

namespace {

constexpr int kBins = 512;

float importance(const float* y, int m) {
  double sum = 0, sum2 = 0;
  for (int i = 0; i < m; ++i) sum += y[i], sum2 += double(y[i]) * double(y[i]);
  const double mean = sum / m;
  return float(std::sqrt(std::max(0.0, sum2 / m - mean * mean)));
}

}  // namespace

TrainingSet buildCoreset(std::uint64_t candidates, int m,
                         const std::function<void(std::uint64_t, float*)>& block,
                         std::uint64_t size, std::uint64_t seed, Progress& progress) {
  TrainingSet set;
  set.m = m;
  if (candidates == 0 || size == 0) return set;
  std::vector<float> y(static_cast<std::size_t>(m), 0.0f);
  if (size >= candidates) {  // every block, weight 1
    progress.begin("collecting training blocks", candidates);
    set.blocks.resize(std::size_t(candidates) * std::size_t(m));
    for (std::uint64_t i = 0; i < candidates; ++i) {
      block(i, set.blocks.data() + i * std::size_t(m));
      set.weights.push_back(1.0f);
      set.source.push_back(i);
      progress.advance();
    }
    progress.end();
    return set;
  }
  progress.begin("coreset: importance", 3 * candidates);
  // Pass 1: the importance range.
  float lo = std::numeric_limits<float>::infinity(), hi = 0;
  for (std::uint64_t i = 0; i < candidates; ++i) {
    block(i, y.data());
    const float v = importance(y.data(), m);
    lo = std::min(lo, v), hi = std::max(hi, v);
    progress.advance();
  }
  const double width = std::max(double(hi) - double(lo), 1e-30);
  auto binOf = [&](float v) {
    return std::clamp(int((double(v) - lo) / width * kBins), 0, kBins - 1);
  };
  // Pass 2: the importance histogram Q_q.
  std::vector<std::uint64_t> q(kBins, 0);
  for (std::uint64_t i = 0; i < candidates; ++i) {
    block(i, y.data());
    ++q[std::size_t(binOf(importance(y.data(), m)))];
    progress.advance();
  }
  // Budgets B_q = min(Q_q, s Q_q imp_q), s fitted so that they sum to `size` (bins whose budget
  // would exceed their count take every block: the paper's saturated high-importance bins).
  std::vector<double> imp(kBins);
  for (int b = 0; b < kBins; ++b)
    imp[std::size_t(b)] = hi > lo ? double(lo) + (b + 0.5) * width / kBins : 1.0;
  // Every non-empty bin keeps at least one block, so the weights still account for every block.
  auto budgetOf = [&](double s, int b) {
    const std::uint64_t count = q[std::size_t(b)];
    if (count == 0) return std::uint64_t(0);
    const double want = std::min(double(count), s * double(count) * imp[std::size_t(b)]);
    return std::clamp<std::uint64_t>(std::uint64_t(std::llround(want)), 1, count);
  };
  auto total = [&](double s) {
    double t = 0;
    for (int b = 0; b < kBins; ++b) t += double(budgetOf(s, b));
    return t;
  };
  double sLo = 0, sHi = 1;
  while (total(sHi) < double(size) && sHi < 1e30) sHi *= 2;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (sLo + sHi);
    (total(mid) < double(size) ? sLo : sHi) = mid;
  }
  std::vector<std::uint64_t> budget(kBins);
  for (int b = 0; b < kBins; ++b) budget[std::size_t(b)] = budgetOf(sLo, b);
  // Pass 3: reservoir sampling per bin (Vitter's algorithm R).
  std::mt19937_64 rng(seed);
  std::vector<std::vector<std::uint64_t>> reservoir(kBins);
  std::vector<std::uint64_t> seen(kBins, 0);
  for (std::uint64_t i = 0; i < candidates; ++i) {
    block(i, y.data());
    const std::size_t b = std::size_t(binOf(importance(y.data(), m)));
    const std::uint64_t n = seen[b]++;
    if (reservoir[b].size() < budget[b]) {
      reservoir[b].push_back(i);
    } else if (budget[b] > 0) {
      const std::uint64_t j = std::uniform_int_distribution<std::uint64_t>(0, n)(rng);
      if (j < budget[b]) reservoir[b][std::size_t(j)] = i;
    }
    progress.advance();
  }
  progress.end();
  std::vector<std::pair<std::uint64_t, float>> picked;
  for (int b = 0; b < kBins; ++b) {
    if (reservoir[std::size_t(b)].empty()) continue;
    const float w =
        float(std::sqrt(double(q[std::size_t(b)]) / double(reservoir[std::size_t(b)].size())));
    for (std::uint64_t i : reservoir[std::size_t(b)]) picked.emplace_back(i, w);
  }
  std::sort(picked.begin(), picked.end());
  set.blocks.resize(picked.size() * std::size_t(m));
  for (std::size_t i = 0; i < picked.size(); ++i) {
    float* out = set.blocks.data() + i * std::size_t(m);
    block(picked[i].first, out);
    for (int v = 0; v < m; ++v) out[v] *= picked[i].second;
    set.weights.push_back(picked[i].second);
    set.source.push_back(picked[i].first);
  }
  return set;
}

// ---- K-SVD ----------------------------------------------------------------------------------

namespace {

// Makes `d` zero-mean (orthogonal to the DC atom) and unit-norm; false when nothing is left.
bool normalizeAtom(float* d, int m) {
  double mean = 0;
  for (int i = 0; i < m; ++i) mean += d[i];
  mean /= m;
  double norm2 = 0;
  for (int i = 0; i < m; ++i) d[i] = float(d[i] - mean), norm2 += double(d[i]) * double(d[i]);
  if (norm2 <= 1e-20) return false;
  const float inv = float(1.0 / std::sqrt(norm2));
  for (int i = 0; i < m; ++i) d[i] *= inv;
  return true;
}

}  // namespace

Dictionary trainDictionary(const TrainingSet& set, const TrainParams& params, Progress& progress,
                           double* rmse,
                           const std::function<void(int, const Dictionary&)>& afterIteration) {
  const int m = set.m, k = params.atoms;
  if (m <= 0 || k < 2) throw std::invalid_argument("K-SVD needs at least 2 atoms");
  Dictionary d;
  d.m = m, d.atoms = k;
  d.values.assign(std::size_t(k) * std::size_t(m), 0.0f);
  for (int i = 0; i < m; ++i) d.atom(0)[i] = float(1.0 / std::sqrt(double(m)));
  // Initial atoms: training blocks in a seeded random order (zero-mean, unit-norm), then random
  // zero-mean directions when the blocks run out.
  std::mt19937_64 rng(params.seed);
  std::vector<std::size_t> order(set.count());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::shuffle(order.begin(), order.end(), rng);
  std::size_t next = 0;
  std::normal_distribution<float> gauss;
  for (int a = 1; a < k; ++a) {
    bool ok = false;
    while (!ok && next < order.size()) {
      std::copy_n(set.block(order[next++]), m, d.atom(a));
      ok = normalizeAtom(d.atom(a), m);
    }
    while (!ok) {
      for (int i = 0; i < m; ++i) d.atom(a)[i] = gauss(rng);
      ok = normalizeAtom(d.atom(a), m);
    }
  }
  const std::size_t n = set.count();
  double weight2 = 0;
  for (float w : set.weights) weight2 += double(w) * double(w);
  std::vector<SparseCode> codes;
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> users(
      static_cast<std::size_t>(k));
  std::vector<float> residuals;
  double lastRmse = 0;
  progress.begin("K-SVD", std::uint64_t(params.iterations) * (n + std::uint64_t(k)));
  for (int it = 0; it < params.iterations; ++it) {
    {
      const Coder coder(d);
      codeAll(coder, set.blocks.data(), n, params.sparsity, params.maxResidual2, params.threads,
              codes, [&](std::size_t c) { progress.advance(c); });
    }
    double err = 0;
    for (const SparseCode& c : codes) err += c.residual2;
    lastRmse = weight2 > 0 ? std::sqrt(err / (double(m) * weight2)) : 0;
    for (auto& u : users) u.clear();
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t s = 1; s < codes[i].atoms.size(); ++s)
        users[std::size_t(codes[i].atoms[s])].emplace_back(std::uint32_t(i), std::uint32_t(s));
    // Blocks by residual, worst first: the replacements for unused atoms.
    std::vector<std::size_t> worst(n);
    std::iota(worst.begin(), worst.end(), std::size_t(0));
    std::sort(worst.begin(), worst.end(), [&](std::size_t a, std::size_t b) {
      return codes[a].residual2 > codes[b].residual2;
    });
    std::size_t nextWorst = 0;
    for (int a = 1; a < k; ++a) {
      const auto& list = users[std::size_t(a)];
      float* atom = d.atom(a);
      if (list.empty()) {
        bool ok = false;
        while (!ok && nextWorst < worst.size() && codes[worst[nextWorst]].residual2 > 0) {
          std::copy_n(set.block(worst[nextWorst++]), m, atom);
          ok = normalizeAtom(atom, m);
        }
        progress.advance();
        continue;
      }
      // The residuals of the blocks that use atom a, without atom a's own contribution.
      residuals.assign(list.size() * std::size_t(m), 0.0f);
      parallelFor(list.size(), list.size() > 64 ? params.threads : 1, [&](std::size_t u) {
        const auto [i, slot] = list[u];
        float* r = residuals.data() + u * std::size_t(m);
        const float* y = set.block(i);
        for (int v = 0; v < m; ++v) r[v] = y[v];
        const SparseCode& c = codes[i];
        for (std::size_t s = 0; s < c.atoms.size(); ++s) {
          if (s == slot) continue;
          const float coef = c.coefficients[s];
          const float* at = d.atom(c.atoms[s]);
          for (int v = 0; v < m; ++v) r[v] -= coef * at[v];
        }
      });
      // One power iteration: d = R g, then g = R^T d.
      std::vector<double> acc(static_cast<std::size_t>(m), 0.0);
      for (std::size_t u = 0; u < list.size(); ++u) {
        const float g = codes[list[u].first].coefficients[list[u].second];
        const float* r = residuals.data() + u * std::size_t(m);
        for (int v = 0; v < m; ++v) acc[std::size_t(v)] += double(g) * double(r[v]);
      }
      std::vector<float> updated(static_cast<std::size_t>(m));
      for (int v = 0; v < m; ++v) updated[std::size_t(v)] = float(acc[std::size_t(v)]);
      if (normalizeAtom(updated.data(), m)) {
        std::copy(updated.begin(), updated.end(), atom);
        for (std::size_t u = 0; u < list.size(); ++u) {
          const float* r = residuals.data() + u * std::size_t(m);
          double g = 0;
          for (int v = 0; v < m; ++v) g += double(r[v]) * double(atom[v]);
          codes[list[u].first].coefficients[list[u].second] = float(g);
        }
      }
      progress.advance();
    }
    if (afterIteration) afterIteration(it, d);
  }
  progress.end();
  if (rmse) *rmse = lastRmse;
  return d;
}

std::uint32_t packPair(int atom, int q, int indexBits, int coefBits) {
  if (indexBits < 1 || indexBits > 16 || coefBits < kMinCoefficientBits ||
      indexBits + coefBits > kMaxPairBits || atom < 0 || atom >= (1 << indexBits) ||
      std::abs(q) > maxQuantized(coefBits))
    throw std::invalid_argument("ksvd pair out of range");
  const std::uint32_t raw = std::uint32_t(q) & ((1u << coefBits) - 1u);
  return std::uint32_t(atom) | (raw << indexBits);
}

void appendBits(std::vector<std::byte>& stream, std::uint64_t& bits, std::uint32_t value,
                int width) {
  if (width <= 0) return;
  const std::uint64_t bit = bits;
  bits += std::uint64_t(width);
  stream.resize((bits + 7) / 8, std::byte{0});
  const std::uint64_t mask = width >= 32 ? 0xFFFFFFFFull : (1ull << width) - 1ull;
  const std::uint64_t shifted = (std::uint64_t(value) & mask) << (bit % 8);
  for (int b = 0; b * 8 < int(bit % 8) + width; ++b)
    stream[bit / 8 + std::uint64_t(b)] |= std::byte(std::uint8_t(shifted >> (8 * b)));
}

void appendPair(std::vector<std::byte>& stream, std::uint64_t pairs, std::uint32_t word,
                int pairBits) {
  std::uint64_t bits = pairs * std::uint64_t(pairBits);
  appendBits(stream, bits, word, pairBits);
}

}  // namespace voxwall::codec::ksvd
