#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <voxwall/master/load_balancer.hpp>

using namespace voxwall;
using node::CostGrid;
using voxwall::Rect;

namespace {

// Every pixel of the screen in exactly one rectangle, every rectangle non-empty.
void expectExactTiling(const std::vector<Rect>& rects, int w, int h, const std::string& what) {
  std::vector<int> covered(std::size_t(w) * std::size_t(h), 0);
  for (const auto& r : rects) {
    ASSERT_GT(r.width, 0) << what;
    ASSERT_GT(r.height, 0) << what;
    ASSERT_GE(r.x, 0) << what;
    ASSERT_GE(r.y, 0) << what;
    ASSERT_LE(r.x + r.width, w) << what;
    ASSERT_LE(r.y + r.height, h) << what;
    for (int y = r.y; y < r.y + r.height; ++y)
      for (int x = r.x; x < r.x + r.width; ++x) covered[std::size_t(y) * std::size_t(w) + x]++;
  }
  for (std::size_t i = 0; i < covered.size(); ++i)
    ASSERT_EQ(covered[i], 1) << what << " pixel " << i % w << "," << i / w;
}

// The true cost of a frame: `weight` per pixel inside `hot`, 1/1000 of it elsewhere.
CostGrid truthGrid(int w, int h, const Rect& hot, int cell = 32) {
  CostGrid g(w, h, cell);
  g.add({0, 0, w, h}, 1e-3 * double(w) * h / double(hot.area()));
  g.add(hot, 1.0);
  return g;
}

// One frame rendered with the balancer's cut under `truth`: each slot measures its own cells
// (what a rank reports) and its time, with multiplicative noise.
std::vector<double> simulate(master::LoadBalancer& b, const CostGrid& truth, std::mt19937& rng,
                             double noise) {
  std::uniform_real_distribution<double> jitter(1 - noise, 1 + noise);
  std::vector<CostGrid> grids;
  std::vector<double> seconds;
  for (const auto& r : b.cut()) {
    CostGrid g(truth.screenWidth, truth.screenHeight, truth.cellPixels);
    double total = 0;
    for (int cy = 0; cy < g.cellsY; ++cy)
      for (int cx = 0; cx < g.cellsX; ++cx) {
        const Rect c = g.cellRect(cx, cy);
        const int x0 = std::max(c.x, r.x), x1 = std::min(c.x + c.width, r.x + r.width);
        const int y0 = std::max(c.y, r.y), y1 = std::min(c.y + c.height, r.y + r.height);
        if (x0 >= x1 || y0 >= y1) continue;
        const double cost = truth.costOf({x0, y0, x1 - x0, y1 - y0});
        g.at(cx, cy) = cost * 2;  // thread-seconds: the balancer rescales them to wall time
        total += cost;
      }
    grids.push_back(g);
    seconds.push_back(total * (noise > 0 ? jitter(rng) : 1.0));
  }
  b.update(grids, seconds);
  return seconds;
}

double trueImbalance(const std::vector<Rect>& cut, const CostGrid& truth) {
  std::vector<double> costs;
  for (const auto& r : cut) costs.push_back(truth.costOf(r));
  return master::imbalance(costs);
}

}  // namespace

TEST(GridCut, CoversTheScreenExactlyOnce) {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 200; ++trial) {
    const int w = 1 + int(rng() % 300), h = 1 + int(rng() % 300);
    const int tx = 1 + int(rng() % std::min(w, 9)), ty = 1 + int(rng() % std::min(h, 9));
    expectExactTiling(master::gridCut(w, h, tx, ty), w, h, "grid");
  }
  EXPECT_THROW(master::gridCut(4, 4, 5, 1), std::invalid_argument);
  EXPECT_THROW(master::gridCut(4, 4, 0, 1), std::invalid_argument);
}

TEST(StripCut, EqualAreaStrips) {
  const auto strips = master::stripCut(100, 10, 3);
  expectExactTiling(strips, 100, 10, "strips");
  for (const auto& s : strips) EXPECT_NEAR(s.height, 10.0 / 3, 1.0);
  EXPECT_THROW(master::stripCut(100, 2, 3), std::invalid_argument);
}

// Property: for random screens, rank counts and cost grids (zeros, negative, NaN and infinite
// cells included) the cut tiles the screen exactly.
TEST(BisectCut, AlwaysTilesTheScreenExactly) {
  std::mt19937 rng(1234);
  for (int trial = 0; trial < 400; ++trial) {
    const int w = 1 + int(rng() % 200), h = 1 + int(rng() % 120);
    const int cell = 1 + int(rng() % 40);
    const int count = 1 + int(rng() % std::min<long long>(64, (long long)w * h));
    CostGrid g(w, h, cell);
    const int kind = int(rng() % 4);
    for (double& v : g.seconds) {
      const double u = std::uniform_real_distribution<double>(0, 1)(rng);
      v = kind == 0 ? u : kind == 1 ? (u < 0.9 ? 0 : u * 100) : kind == 2 ? 0 : u;
      if (kind == 3 && rng() % 10 == 0) {
        const double weird[] = {-1, NAN, INFINITY, -INFINITY, 1e300};
        v = weird[rng() % 5];
      }
    }
    const auto cut = master::bisectCut(g, {0, 0, w, h}, count);
    ASSERT_EQ(cut.size(), std::size_t(count));
    expectExactTiling(cut, w, h,
                      std::to_string(w) + "x" + std::to_string(h) + " into " +
                          std::to_string(count) + " (kind " + std::to_string(kind) + ")");
  }
  // As many ranks as pixels still works; more does not.
  CostGrid tiny(3, 3, 2);
  expectExactTiling(master::bisectCut(tiny, {0, 0, 3, 3}, 9), 3, 3, "3x3 into 9");
  EXPECT_THROW(master::bisectCut(tiny, {0, 0, 3, 3}, 10), std::invalid_argument);
}

TEST(BisectCut, BalancesASkewedCost) {
  const CostGrid truth = truthGrid(1920, 1080, {0, 0, 480, 270});
  for (int ranks : {2, 3, 4, 7, 16}) {
    const auto cut = master::bisectCut(truth, {0, 0, 1920, 1080}, ranks);
    EXPECT_LT(trueImbalance(cut, truth), 1.05) << ranks << " ranks";
  }
}

// The balancer's goal: the volume covers only a corner of the screen. Static strips leave most
// ranks idle; the dynamic balancer is within 1.15 after five frames.
TEST(LoadBalancer, CornerViewBalancesWithinFiveFrames) {
  const CostGrid truth = truthGrid(1920, 1080, {0, 0, 560, 300});
  for (int ranks : {2, 3, 4, 8}) {
    master::LoadBalancer b(1920, 1080, ranks);
    const double strips = trueImbalance(b.cut(), truth);
    std::mt19937 rng(ranks);
    for (int f = 0; f < 5; ++f) simulate(b, truth, rng, 0.03);
    const double dynamic = trueImbalance(b.cut(), truth);
    EXPECT_GT(strips, 1.9) << ranks << " ranks";
    EXPECT_LE(dynamic, 1.15) << ranks << " ranks, strips " << strips;
  }
}

// Damping: with a still camera and noisy timings the cut settles and then stays put.
TEST(LoadBalancer, StillCameraSettlesWithoutJitter) {
  const CostGrid truth = truthGrid(1280, 720, {200, 100, 600, 500});
  master::LoadBalancer b(1280, 720, 4);
  std::mt19937 rng(99);
  for (int f = 0; f < 10; ++f) simulate(b, truth, rng, 0.04);
  const auto settled = b.cut();
  const int recuts = b.recuts();
  for (int f = 0; f < 40; ++f) simulate(b, truth, rng, 0.04);
  EXPECT_EQ(b.cut(), settled);
  EXPECT_EQ(b.recuts(), recuts);
  EXPECT_LE(trueImbalance(b.cut(), truth), 1.1);
}

// A sudden change of view re-balances within a few frames.
TEST(LoadBalancer, FollowsASuddenChangeOfView) {
  const CostGrid before = truthGrid(1920, 1080, {0, 0, 500, 300});
  const CostGrid after = truthGrid(1920, 1080, {1300, 700, 620, 380});
  master::LoadBalancer b(1920, 1080, 4);
  std::mt19937 rng(5);
  for (int f = 0; f < 8; ++f) simulate(b, before, rng, 0.03);
  ASSERT_LE(trueImbalance(b.cut(), before), 1.15);
  EXPECT_GT(trueImbalance(b.cut(), after), 2.0);
  for (int f = 0; f < 3; ++f) simulate(b, after, rng, 0.03);
  EXPECT_LE(trueImbalance(b.cut(), after), 1.15);
}

// A rank that reports nonsense (NaN, negative, infinite or gigantic numbers) cannot break the
// cut: it still tiles the screen, and honest frames bring the balance back.
TEST(LoadBalancer, AbsurdReportsDoNotBreakTheCut) {
  const CostGrid truth = truthGrid(640, 480, {0, 0, 200, 150});
  const double absurd[] = {NAN, -5, INFINITY, 1e300, 0};
  for (double bad : absurd) {
    master::LoadBalancer b(640, 480, 3);
    std::mt19937 rng(1);
    for (int f = 0; f < 3; ++f) simulate(b, truth, rng, 0);
    std::vector<CostGrid> grids(3, CostGrid(640, 480, 32));
    std::vector<double> seconds = {0.1, bad, 0.1};
    for (auto& g : grids) g.seconds.assign(g.seconds.size(), bad);
    b.update(grids, seconds);
    expectExactTiling(b.cut(), 640, 480, "after bad value " + std::to_string(bad));
    // Grids of the wrong size are refused, not read out of bounds.
    EXPECT_THROW(b.update({CostGrid(64, 48, 32)}, {1.0}), std::invalid_argument);
    for (int f = 0; f < 5; ++f) simulate(b, truth, rng, 0);
    expectExactTiling(b.cut(), 640, 480, "recovered");
    EXPECT_LE(trueImbalance(b.cut(), truth), 1.15) << "after bad value " << bad;
  }
}
