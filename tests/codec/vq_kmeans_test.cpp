#include <gtest/gtest.h>

#include <random>
#include <voxwall/codec/vq_kmeans.hpp>

using namespace voxwall::codec;
using namespace voxwall::codec::vq;

namespace {

// Points around a few random centres (so clusters exist), all distinct.
std::vector<Point> clustered(std::size_t n, int groups, int spread, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Point> centres(static_cast<std::size_t>(groups));
  std::uniform_int_distribution<int> any(spread, 4000);
  for (auto& c : centres)
    for (auto& x : c) x = std::uint16_t(any(rng));
  std::uniform_int_distribution<int> jitter(-spread, spread);
  std::vector<Point> points(n);
  for (std::size_t i = 0; i < n; ++i)
    for (int d = 0; d < kDims; ++d)
      points[i][d] = std::uint16_t(centres[i % centres.size()][d] + jitter(rng));
  return points;
}

std::vector<std::uint32_t> randomWeights(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> w(1, 50);
  std::vector<std::uint32_t> out(n);
  for (auto& x : out) x = std::uint32_t(w(rng));
  return out;
}

}  // namespace

class KMeansMatchesBruteForce
    : public ::testing::TestWithParam<std::tuple<std::size_t, std::size_t, int>> {};

TEST_P(KMeansMatchesBruteForce, SameCentresAndAssignment) {
  const auto [n, k, spread] = GetParam();
  const auto points = clustered(n, 7, spread, unsigned(n * 31 + k));
  const auto weights = randomWeights(n, unsigned(k));
  voxwall::Progress quiet;
  const KMeansResult fast = kmeans(points, weights, k, 100, 2, quiet);
  const KMeansResult ref = kmeansBruteForce(points, weights, k, 100);
  ASSERT_EQ(fast.centers.size(), std::min(k, n));
  EXPECT_EQ(fast.assignment, ref.assignment);
  EXPECT_EQ(fast.centers, ref.centers);
  EXPECT_EQ(fast.iterations, ref.iterations);
  EXPECT_EQ(fast.converged, ref.converged);
  // The pruning saves work: fewer full distances than the plain algorithm.
  if (k > 1) {
    EXPECT_LT(fast.computed, ref.computed);
  }
  EXPECT_LE(fast.computed, ref.computed);
  EXPECT_EQ(fast.plainEquivalent, ref.plainEquivalent);
  // Every point is assigned to its nearest centre.
  for (std::size_t i = 0; i < n; ++i) {
    auto dist = [&](std::size_t c) {
      double s = 0;
      for (int d = 0; d < kDims; ++d) {
        const double diff = double(points[i][d]) - fast.centers[c][d];
        s += diff * diff;
      }
      return s;
    };
    const double own = dist(fast.assignment[i]);
    for (std::size_t c = 0; c < fast.centers.size(); ++c)
      ASSERT_LE(own, dist(c) * (1 + 1e-9) + 1e-6) << "point " << i;
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, KMeansMatchesBruteForce,
                         ::testing::Values(std::make_tuple(std::size_t(50), std::size_t(1), 30),
                                           std::make_tuple(std::size_t(200), std::size_t(7), 30),
                                           std::make_tuple(std::size_t(300), std::size_t(20), 200),
                                           std::make_tuple(std::size_t(400), std::size_t(64), 600),
                                           std::make_tuple(std::size_t(120), std::size_t(119),
                                                           50)));

TEST(KMeans, DeterministicForAnyThreadCount) {
  const auto points = clustered(2000, 12, 300, 4);
  const auto weights = randomWeights(points.size(), 9);
  voxwall::Progress quiet;
  const auto one = kmeans(points, weights, 40, 30, 1, quiet);
  const auto two = kmeans(points, weights, 40, 30, 2, quiet);
  const auto four = kmeans(points, weights, 40, 30, 4, quiet);
  EXPECT_EQ(one.assignment, two.assignment);
  EXPECT_EQ(one.centers, four.centers);
  EXPECT_EQ(one.computed, four.computed);
}

TEST(KMeans, MoreCentresThanPointsKeepsEveryPoint) {
  const auto points = clustered(30, 3, 10, 2);
  const std::vector<std::uint32_t> weights(30, 1);
  voxwall::Progress quiet;
  const auto r = kmeans(points, weights, 100, 10, 1, quiet);
  ASSERT_EQ(r.centers.size(), 30u);
  for (std::size_t i = 0; i < 30; ++i)
    for (int d = 0; d < kDims; ++d) EXPECT_EQ(r.centers[r.assignment[i]][d], double(points[i][d]));
}

TEST(KMeans, WeightsPullTheCentre) {
  // Two points, one centre: the centre is their weighted mean.
  Point a{}, b{};
  b.fill(100);
  const std::vector<Point> points = {a, b};
  const std::vector<std::uint32_t> weights = {3, 1};
  voxwall::Progress quiet;
  const auto r = kmeans(points, weights, 1, 10, 1, quiet);
  ASSERT_EQ(r.centers.size(), 1u);
  EXPECT_DOUBLE_EQ(r.centers[0][0], 25.0);
}

TEST(KMeans, RefusesBadInput) {
  voxwall::Progress quiet;
  const std::vector<Point> points(3);
  const std::vector<std::uint32_t> weights(2, 1);
  EXPECT_THROW(kmeans(points, weights, 2, 10, 1, quiet), std::invalid_argument);
  EXPECT_THROW(kmeans({}, {}, 2, 10, 1, quiet), std::invalid_argument);
}
