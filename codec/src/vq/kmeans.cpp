// Weighted k-means for the VQ codec; the algorithm is described in vq_kmeans.hpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <stdexcept>
#include <voxwall/codec/vq_kmeans.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec::vq {
namespace {

using Center = std::array<double, kDims>;
constexpr double kInf = std::numeric_limits<double>::infinity();

std::uint64_t squaredNorm(const Point& p) {
  std::uint64_t s = 0;
  for (int i = 0; i < kDims; ++i) s += std::uint64_t(p[i]) * p[i];
  return s;
}

// Exact squared distance between two points (integers), as a double.
double pointDistance(const Point& a, std::uint64_t aa, const Point& b, std::uint64_t bb) {
  std::uint64_t dot = 0;
  for (int i = 0; i < kDims; ++i) dot += std::uint64_t(a[i]) * b[i];
  return double(aa + bb - 2 * dot);
}

// |a|^2 + |c|^2 - 2 a.c (the paper's form), clamped at 0 against rounding.
double centerDistance(const Point& a, double aa, const Center& c, double cc) {
  double dot = 0;
  for (int i = 0; i < kDims; ++i) dot += double(a[i]) * c[i];
  const double d = aa + cc - 2.0 * dot;
  return d > 0 ? d : 0.0;
}

struct Counters {
  std::uint64_t computed = 0, skipped = 0;
};

// Shared state of the clustering.
struct State {
  std::span<const Point> points;
  std::span<const std::uint32_t> weights;
  std::vector<double> pointSq, pointNorm;
  std::vector<Center> centers;
  std::vector<double> centerSq, centerNorm;
  std::vector<std::uint32_t> assignment;
  std::vector<double> p;  // squared distance to the assigned centre

  void setCenterNorm(std::size_t c) {
    double s = 0;
    for (int i = 0; i < kDims; ++i) s += centers[c][i] * centers[c][i];
    centerSq[c] = s;
    centerNorm[c] = std::sqrt(s);
  }

  // Algorithm 1: the squared distance, or dmax when the norm difference proves it is not less.
  double distanceS(double dmax, std::size_t point, std::size_t c, Counters& n) const {
    const double diff = pointNorm[point] - centerNorm[c];
    if (diff * diff >= dmax) {
      ++n.skipped;
      return dmax;
    }
    ++n.computed;
    return centerDistance(points[point], pointSq[point], centers[c], centerSq[c]);
  }

  // Weighted means of the members; returns which centres moved.
  std::vector<char> updateCenters() {
    const std::size_t k = centers.size();
    std::vector<Center> sum(k, Center{});
    std::vector<double> weight(k, 0.0);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const std::size_t c = assignment[i];
      const double w = weights[i];
      for (int d = 0; d < kDims; ++d) sum[c][d] += w * double(points[i][d]);
      weight[c] += w;
    }
    std::vector<char> changed(k, 0);
    for (std::size_t c = 0; c < k; ++c) {
      if (weight[c] <= 0) continue;  // an empty cluster keeps its centre
      Center next;
      for (int d = 0; d < kDims; ++d) next[d] = sum[c][d] / weight[c];
      if (next != centers[c]) {
        centers[c] = next;
        setCenterNorm(c);
        changed[c] = 1;
      }
    }
    return changed;
  }
};

// Centres sorted by norm, for the outward walk in the iterations.
struct NormOrder {
  std::vector<std::uint32_t> center;
  std::vector<double> norm;
  std::vector<char> contains;  // per centre: in this list
  static NormOrder make(const State& s, const std::vector<char>& changed, bool onlyChanged) {
    NormOrder o;
    const std::size_t k = s.centers.size();
    o.contains.assign(k, 0);
    for (std::uint32_t c = 0; c < k; ++c)
      if (!onlyChanged || changed[c]) o.center.push_back(c), o.contains[c] = 1;
    std::sort(o.center.begin(), o.center.end(), [&](std::uint32_t a, std::uint32_t b) {
      return s.centerNorm[a] < s.centerNorm[b] || (s.centerNorm[a] == s.centerNorm[b] && a < b);
    });
    o.norm.reserve(o.center.size());
    for (const auto c : o.center) o.norm.push_back(s.centerNorm[c]);
    return o;
  }
};

void checkInput(std::span<const Point> points, std::span<const std::uint32_t> weights,
                std::size_t k) {
  if (points.size() != weights.size())
    throw std::invalid_argument("k-means: one weight per point is needed");
  if (points.empty() || k == 0) throw std::invalid_argument("k-means: nothing to cluster");
  if (points.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("k-means: too many points");
}

State makeState(std::span<const Point> points, std::span<const std::uint32_t> weights) {
  State s;
  s.points = points;
  s.weights = weights;
  s.pointSq.resize(points.size());
  s.pointNorm.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    s.pointSq[i] = double(squaredNorm(points[i]));
    s.pointNorm[i] = std::sqrt(s.pointSq[i]);
  }
  s.assignment.assign(points.size(), 0);
  s.p.assign(points.size(), kInf);
  return s;
}

std::size_t closestToOrigin(const State& s) {
  std::size_t best = 0;
  for (std::size_t i = 1; i < s.points.size(); ++i)
    if (s.pointSq[i] < s.pointSq[best]) best = i;
  return best;
}

void addPointAsCenter(State& s, std::size_t point) {
  Center c;
  for (int d = 0; d < kDims; ++d) c[d] = double(s.points[point][d]);
  s.centers.push_back(c);
  s.centerSq.push_back(0), s.centerNorm.push_back(0);
  s.setCenterNorm(s.centers.size() - 1);
}

// Lloyd's loop: the centres move to their members' means, then `reassign(changed)` (which centres
// moved) assigns the points again, until no centre moves or after maxIterations passes.
struct Iterated {
  int iterations = 0;
  bool converged = false;
};
template <class Reassign>
Iterated iterate(State& s, int maxIterations, Reassign&& reassign) {
  Iterated r;
  while (r.iterations < maxIterations) {
    const std::vector<char> changed = s.updateCenters();
    if (std::find(changed.begin(), changed.end(), 1) == changed.end()) {
      r.converged = true;
      break;
    }
    ++r.iterations;
    reassign(changed);
  }
  return r;
}

KMeansResult finish(State& s, int iterations, bool converged, std::uint64_t computed,
                    std::uint64_t skipped, std::uint64_t plain) {
  KMeansResult r;
  r.centers = std::move(s.centers);
  r.assignment = std::move(s.assignment);
  r.iterations = iterations;
  r.converged = converged;
  r.computed = computed, r.skipped = skipped, r.plainEquivalent = plain;
  return r;
}

}  // namespace

KMeansResult kmeans(std::span<const Point> points, std::span<const std::uint32_t> weights,
                    std::size_t k, int maxIterations, int threads, Progress& progress) {
  checkInput(points, weights, k);
  const std::size_t n = points.size();
  k = std::min(k, n);
  State s = makeState(points, weights);
  std::uint64_t computed = 0, skipped = 0;
  const std::uint64_t plainPerPass = std::uint64_t(n) * k;

  // ---- Algorithm 2: furthest-first centres, lazily updated priority queue ----
  // Points are compared exactly (integers); `eval` counts the centres a point has seen.
  std::vector<std::uint32_t> eval(n, 0);
  progress.begin("k-means: furthest-first centres", k);
  const std::size_t first = closestToOrigin(s);
  addPointAsCenter(s, first);
  s.p[first] = 0, s.assignment[first] = 0, eval[first] = 1;
  // Max-heap on distance; equal distances pop the lower index first.
  auto lower = [&](std::uint32_t a, std::uint32_t b) {
    return s.p[a] < s.p[b] || (s.p[a] == s.p[b] && a > b);
  };
  std::vector<std::uint32_t> heap;
  heap.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (i == first) continue;
    ++computed;
    s.p[i] = pointDistance(points[i], std::uint64_t(s.pointSq[i]), points[first],
                           std::uint64_t(s.pointSq[first]));
    eval[i] = 1;
    heap.push_back(std::uint32_t(i));
  }
  std::make_heap(heap.begin(), heap.end(), lower);
  progress.advance();
  Counters initCount;
  while (s.centers.size() < k) {
    std::pop_heap(heap.begin(), heap.end(), lower);
    const std::uint32_t cw = heap.back();
    heap.pop_back();
    while (eval[cw] < s.centers.size()) {
      const std::size_t c = eval[cw];
      // The centre is a point, so the distance is exact (integers).
      const double d = s.distanceS(s.p[cw], cw, c, initCount);
      if (d < s.p[cw]) s.p[cw] = d, s.assignment[cw] = std::uint32_t(c);
      ++eval[cw];
    }
    if (heap.empty() || !lower(cw, heap.front())) {
      // Still the furthest: it becomes a centre.
      s.assignment[cw] = std::uint32_t(s.centers.size());
      s.p[cw] = 0;
      addPointAsCenter(s, cw);
      eval[cw] = std::uint32_t(s.centers.size());
      progress.advance();
    } else {
      heap.push_back(cw);
      std::push_heap(heap.begin(), heap.end(), lower);
    }
  }
  progress.end();

  // ---- Algorithm 4, first part: every point checks the centres it has not seen ----
  const std::size_t chunk = 256;
  const std::size_t chunks = (n + chunk - 1) / chunk;
  std::vector<Counters> perChunk(chunks);
  parallelFor(chunks, threads, [&](std::size_t ci) {
    Counters& cnt = perChunk[ci];
    for (std::size_t i = ci * chunk; i < std::min(n, (ci + 1) * chunk); ++i)
      for (; eval[i] < k; ++eval[i]) {
        const double d = s.distanceS(s.p[i], i, eval[i], cnt);
        if (d < s.p[i]) s.p[i] = d, s.assignment[i] = eval[i];
      }
  });
  for (const auto& c : perChunk) computed += c.computed, skipped += c.skipped;
  computed += initCount.computed, skipped += initCount.skipped;

  // ---- Algorithm 4: update centres, then re-check only what a changed centre can affect ----
  progress.begin("k-means: iterations", std::uint64_t(std::max(0, maxIterations)));
  const Iterated it = iterate(s, maxIterations, [&](const std::vector<char>& changed) {
    const NormOrder all = NormOrder::make(s, changed, false);
    const NormOrder changedOrder = NormOrder::make(s, changed, true);
    std::fill(perChunk.begin(), perChunk.end(), Counters{});
    parallelFor(chunks, threads, [&](std::size_t ci) {
      Counters& cnt = perChunk[ci];
      for (std::size_t i = ci * chunk; i < std::min(n, (ci + 1) * chunk); ++i) {
        const std::uint32_t own = s.assignment[i];
        double d = s.p[i];
        if (changed[own]) {
          ++cnt.computed;
          d = centerDistance(points[i], s.pointSq[i], s.centers[own], s.centerSq[own]);
        }
        if (d <= 0) {
          s.p[i] = 0;
          continue;
        }
        // Algorithm 3 over every centre (moved away from its own) or the changed ones. The
        // candidates are walked outward from the point's norm, nearest norm first: once the
        // norm bound (Algorithm 1) rules out the nearer of the next two, it rules out all the
        // rest, which are counted as skipped without being touched.
        std::uint32_t best = own;
        double bestD = d;
        const NormOrder& order = d > s.p[i] ? all : changedOrder;
        const double np = s.pointNorm[i];
        std::size_t hi = std::size_t(std::lower_bound(order.norm.begin(), order.norm.end(), np) -
                                     order.norm.begin());
        std::size_t lo = hi;  // candidates [lo, hi) visited
        std::size_t visited = 0;
        for (;;) {
          const bool canDown = lo > 0, canUp = hi < order.norm.size();
          if (!canDown && !canUp) break;
          const bool down = canDown && (!canUp || np - order.norm[lo - 1] <= order.norm[hi] - np);
          const std::size_t at = down ? --lo : hi++;
          const std::uint32_t c = order.center[at];
          if (c == own) continue;
          const double diff = order.norm[at] - np;
          if (diff * diff >= bestD) break;
          ++visited;
          const double dn = s.distanceS(bestD, i, c, cnt);
          if (dn < bestD) bestD = dn, best = c;
        }
        const std::size_t candidates = order.center.size() - (order.contains[own] ? 1 : 0);
        cnt.skipped += candidates - visited;
        s.assignment[i] = best;
        s.p[i] = bestD;
      }
    });
    for (const auto& c : perChunk) computed += c.computed, skipped += c.skipped;
    progress.advance();
  });
  progress.end();
  const std::uint64_t plain = plainPerPass * std::uint64_t(it.iterations + 1);
  return finish(s, it.iterations, it.converged, computed, skipped, plain);
}

KMeansResult kmeansBruteForce(std::span<const Point> points, std::span<const std::uint32_t> weights,
                              std::size_t k, int maxIterations) {
  checkInput(points, weights, k);
  const std::size_t n = points.size();
  k = std::min(k, n);
  State s = makeState(points, weights);
  std::uint64_t computed = 0;
  std::vector<char> isCenter(n, 0);
  const std::size_t first = closestToOrigin(s);
  addPointAsCenter(s, first);
  isCenter[first] = 1;
  std::vector<double> minD(n, kInf);
  for (;;) {
    const std::size_t c = s.centers.size() - 1;
    for (std::size_t i = 0; i < n; ++i) {
      ++computed;
      const double d = centerDistance(points[i], s.pointSq[i], s.centers[c], s.centerSq[c]);
      if (d < minD[i]) minD[i] = d, s.assignment[i] = std::uint32_t(c);
    }
    if (s.centers.size() == k) break;
    std::size_t far = n;
    for (std::size_t i = 0; i < n; ++i)
      if (!isCenter[i] && (far == n || minD[i] > minD[far])) far = i;
    addPointAsCenter(s, far);
    isCenter[far] = 1;
  }
  s.p = minD;
  const Iterated it = iterate(s, maxIterations, [&](const std::vector<char>&) {
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t own = s.assignment[i];
      ++computed;
      double best = centerDistance(points[i], s.pointSq[i], s.centers[own], s.centerSq[own]);
      std::uint32_t bestC = own;
      for (std::uint32_t c = 0; c < k; ++c) {
        if (c == own) continue;
        ++computed;
        const double d = centerDistance(points[i], s.pointSq[i], s.centers[c], s.centerSq[c]);
        if (d < best) best = d, bestC = c;
      }
      s.assignment[i] = bestC;
    }
  });
  return finish(s, it.iterations, it.converged, computed, 0,
                std::uint64_t(n) * k * std::uint64_t(it.iterations + 1));
}

}  // namespace voxwall::codec::vq
