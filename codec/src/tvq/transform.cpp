// The tvq codec's block transforms (Fout and Ma, section 4.1) and the classification of section
// 4.2.1.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec::tvq {

const char* className(int c) {
  static const char* const names[kClasses] = {"ZERO",  "LP",   "BPx",  "BPy",  "BPz",
                                              "BPxyz", "HPxy", "HPxz", "HPyz", "HPxyz"};
  return c >= 0 && c < kClasses ? names[c] : "?";
}

std::uint8_t classZones(int c) {
  // Zone bits: 1 high x, 2 high y, 4 high z. The bandpass zones are 1, 2, 4; the highpass zones
  // 3 (xy), 5 (xz), 6 (yz) and 7 (xyz). A highpass class keeps the whole bandpass partition.
  constexpr std::uint8_t lp = 1u << 0, bp = (1u << 1) | (1u << 2) | (1u << 4);
  static const std::uint8_t zones[kClasses] = {0,
                                               lp,
                                               lp | 1u << 1,
                                               lp | 1u << 2,
                                               lp | 1u << 4,
                                               lp | bp,
                                               lp | bp | 1u << 3,
                                               lp | bp | 1u << 5,
                                               lp | bp | 1u << 6,
                                               0xFF};
  return c >= 0 && c < kClasses ? zones[c] : 0;
}

void Basis::forward(const float* x, float* c) const {
  for (int k = 0; k < kBlockVoxels; ++k) {
    const float* r = row(k);
    float sum = 0;
    for (int i = 0; i < kBlockVoxels; ++i) sum += r[i] * x[i];
    c[k] = sum;
  }
}

void Basis::inverse(const float* c, float* x) const {
  for (int i = 0; i < kBlockVoxels; ++i) x[i] = 0;
  for (int k = 0; k < kBlockVoxels; ++k) {
    const float* r = row(k);
    for (int i = 0; i < kBlockVoxels; ++i) x[i] += c[k] * r[i];
  }
}

namespace {

// 1D orthonormal DCT-II of length 4: d[u][i].
double dct4(int u, int i) {
  const double a = u == 0 ? std::sqrt(0.25) : std::sqrt(0.5);
  return a * std::cos((2 * i + 1) * u * std::numbers::pi / 8.0);
}

Eigen::MatrixXd dctMatrix() {
  Eigen::MatrixXd d(kBlockVoxels, kBlockVoxels);
  for (int k = 0; k < kBlockVoxels; ++k)
    for (int i = 0; i < kBlockVoxels; ++i)
      d(k, i) = dct4(k & 3, i & 3) * dct4((k >> 2) & 3, (i >> 2) & 3) * dct4(k >> 4, i >> 4);
  return d;
}

int dctZone(int k) {
  return int((k & 3) >= 2) | (int(((k >> 2) & 3) >= 2) << 1) | (int((k >> 4) >= 2) << 2);
}

}  // namespace

Basis dctBasis() {
  const Eigen::MatrixXd d = dctMatrix();
  Basis b;
  for (int k = 0; k < kBlockVoxels; ++k) {
    b.zone[std::size_t(k)] = std::uint8_t(dctZone(k));
    for (int i = 0; i < kBlockVoxels; ++i)
      b.rows[std::size_t(k * kBlockVoxels + i)] = float(d(k, i));
  }
  return b;
}

Basis kltBasis(std::uint64_t count, const std::function<void(std::uint64_t, float*)>& block,
               int threads, Progress& progress,
               const std::function<void(std::uint64_t, std::uint64_t)>& prepare) {
  // The covariance of the mean-removed blocks, summed per chunk in double and the chunks summed
  // in order (the same basis whatever the threads), a batch of chunks at a time.
  const int workers = std::max(1, resolveThreads(threads));
  const std::uint64_t chunk = 4096, batch = 16;
  const std::uint64_t chunks = (count + chunk - 1) / chunk;
  std::vector<Eigen::MatrixXd> partial(static_cast<std::size_t>(chunks));
  progress.begin("tvq: KLT covariance", chunks);
  for (std::uint64_t first = 0; first < chunks; first += batch) {
    const std::uint64_t last = std::min(chunks, first + batch);
    if (prepare) prepare(first * chunk, std::min(count, last * chunk));
    parallelFor(std::size_t(last - first), workers, [&](std::size_t inBatch) {
      const std::size_t c = std::size_t(first) + inBatch;
      Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(kBlockVoxels, kBlockVoxels);
      Eigen::Matrix<double, kBlockVoxels, Eigen::Dynamic> xs(kBlockVoxels, 256);
      float x[kBlockVoxels];
      int filled = 0;
      const std::uint64_t end = std::min(count, (c + 1) * chunk);
      for (std::uint64_t i = c * chunk; i < end; ++i) {
        block(i, x);
        double mean = 0;
        for (float v : x) mean += v;
        mean /= kBlockVoxels;
        for (int j = 0; j < kBlockVoxels; ++j) xs(j, filled) = double(x[j]) - mean;
        if (++filled == 256) sum.noalias() += xs * xs.transpose(), filled = 0;
      }
      if (filled) sum.noalias() += xs.leftCols(filled) * xs.leftCols(filled).transpose();
      partial[c] = std::move(sum);
      progress.advance();
    });
  }
  progress.end();
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(kBlockVoxels, kBlockVoxels);
  for (const auto& p : partial) cov += p;
  if (count) cov /= double(count);

  // Eigenvectors within the orthogonal complement of the constant (spanned by DCT rows 1..63),
  // so that basis vector 0 stays the constant even where the data leaves directions unused.
  const Eigen::MatrixXd d = dctMatrix();
  const Eigen::MatrixXd q = d.bottomRows(kBlockVoxels - 1).transpose();  // 64 x 63
  const Eigen::MatrixXd inner = q.transpose() * cov * q;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(inner);
  const Eigen::MatrixXd vectors = q * solver.eigenvectors();  // columns, increasing eigenvalue
  // Decreasing eigenvalue, each vector re-orthonormalized against those before it (Gram-Schmidt
  // in double: the float basis is then orthonormal to ~1e-7).
  Eigen::MatrixXd rows(kBlockVoxels, kBlockVoxels);
  rows.row(0).setConstant(1.0 / 8.0);
  for (int k = 1; k < kBlockVoxels; ++k) {
    Eigen::VectorXd v = vectors.col(kBlockVoxels - 1 - k);
    for (int j = 0; j < k; ++j) v -= rows.row(j).dot(v) * rows.row(j).transpose();
    rows.row(k) = v.normalized().transpose();
  }

  // Zones: each KLT vector goes to the zone where the DCT finds most of its energy, the zones
  // keeping the DCT's sizes (7 AC coefficients in zone 0, 8 in each other). Pairs are taken by
  // decreasing energy fraction, so a vector gets the best zone that still has room.
  std::array<int, 8> room{7, 8, 8, 8, 8, 8, 8, 8};
  struct Pair {
    double energy;
    int vector, zone;
  };
  std::vector<Pair> pairs;
  for (int k = 1; k < kBlockVoxels; ++k) {
    std::array<double, 8> e{};
    for (int j = 1; j < kBlockVoxels; ++j) {
      const double c = d.row(j).dot(rows.row(k));
      e[std::size_t(dctZone(j))] += c * c;
    }
    for (int z = 0; z < 8; ++z) pairs.push_back({e[std::size_t(z)], k, z});
  }
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const Pair& a, const Pair& b) { return a.energy > b.energy; });
  Basis b;
  std::array<bool, kBlockVoxels> placed{};
  placed[0] = true;
  b.zone[0] = 0;
  for (const Pair& p : pairs) {
    if (placed[std::size_t(p.vector)] || room[std::size_t(p.zone)] == 0) continue;
    placed[std::size_t(p.vector)] = true;
    --room[std::size_t(p.zone)];
    b.zone[std::size_t(p.vector)] = std::uint8_t(p.zone);
  }
  for (int k = 0; k < kBlockVoxels; ++k)
    for (int i = 0; i < kBlockVoxels; ++i)
      b.rows[std::size_t(k * kBlockVoxels + i)] = float(rows(k, i));
  return b;
}

int classify(const Basis& basis, const float* c, double maxError2, bool classified) {
  std::array<double, 8> e{};
  for (int k = 1; k < kBlockVoxels; ++k)
    e[basis.zone[std::size_t(k)]] += double(c[k]) * double(c[k]);
  double total = 0;
  for (double v : e) total += v;
  auto error = [&](int cls) {
    const std::uint8_t keep = classZones(cls);
    double dropped = 0;
    for (int z = 0; z < 8; ++z)
      if (!(keep & (1u << z))) dropped += e[std::size_t(z)];
    return dropped;
  };
  if (total <= maxError2) return kZero;
  if (!classified) return kHpXyz;
  // Cheapest first; classes of equal cost (BPx/BPy/BPz, HPxy/HPxz/HPyz) by the smaller error.
  static const int groups[][3] = {
      {kLp, -1, -1}, {kBpX, kBpY, kBpZ}, {kBpXyz, -1, -1}, {kHpXy, kHpXz, kHpYz}};
  for (const auto& g : groups) {
    int best = -1;
    double bestError = 0;
    for (int cls : g) {
      if (cls < 0) continue;
      const double err = error(cls);
      if (err <= maxError2 && (best < 0 || err < bestError)) best = cls, bestError = err;
    }
    if (best >= 0) return best;
  }
  return kHpXyz;
}

}  // namespace voxwall::codec::tvq
