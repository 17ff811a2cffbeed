// The ksvd codec: its learning parts (OMP, K-SVD, the coreset, pair packing) and its files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/codec/ksvd_device.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/text.hpp>

#include "support/format_error_expect.hpp"
#include "support/ksvd_layout1.hpp"
#include "support/sections.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::poke;
using voxwall::test::section;

namespace {

// K unit-norm atoms of m values: the DC atom, then random zero-mean directions.
ksvd::Dictionary randomDictionary(int m, int k, unsigned seed) {
  ksvd::Dictionary d;
  d.m = m, d.atoms = k;
  d.values.resize(std::size_t(m) * std::size_t(k));
  std::mt19937 rng(seed);
  std::normal_distribution<float> n;
  for (int i = 0; i < m; ++i) d.atom(0)[i] = float(1 / std::sqrt(double(m)));
  for (int a = 1; a < k; ++a) {
    float* v = d.atom(a);
    double mean = 0, norm = 0;
    for (int i = 0; i < m; ++i) v[i] = n(rng), mean += v[i];
    for (int i = 0; i < m; ++i) v[i] = float(v[i] - mean / m), norm += double(v[i]) * v[i];
    for (int i = 0; i < m; ++i) v[i] = float(v[i] / std::sqrt(norm));
  }
  return d;
}

// Smooth blocks of m = side^3 values: a random offset, gradient and bump, each with its own
// spread, so importances differ.
std::vector<float> smoothBlocks(int side, std::size_t count, unsigned seed) {
  const int m = side * side * side;
  std::vector<float> out(count * std::size_t(m));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1), amp(0.1f, 1.0f);
  for (std::size_t b = 0; b < count; ++b) {
    const float a = amp(rng), gx = u(rng), gy = u(rng), gz = u(rng), c = u(rng) + 2, w = u(rng);
    for (int z = 0, i = 0; z < side; ++z)
      for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x, ++i)
          out[b * std::size_t(m) + std::size_t(i)] = c +
                                                     a * (gx * x + gy * y + gz * z) / float(side) +
                                                     a * w * std::sin(float(x * y + z) * 0.7f);
  }
  return out;
}

ksvd::Params quick(int side = 6) {
  ksvd::Params p;
  p.blockSide = side, p.atoms = 32, p.sparsity = 6, p.iterations = 5, p.threads = 2;
  p.levels = 1;  // level 0 only: the pyramid has its own tests
  return p;
}

}  // namespace

TEST(KsvdLearning, DcAtomStaysFixedAndAtomsStayUnitNormAfterEveryIteration) {
  const int m = 64;
  ksvd::TrainingSet set;
  set.m = m;
  set.blocks = smoothBlocks(4, 600, 1);
  set.weights.assign(600, 1.0f);
  set.source.resize(600);
  ksvd::TrainParams tp;
  tp.atoms = 40, tp.sparsity = 5, tp.iterations = 6, tp.threads = 2;
  Progress quiet;
  int iterations = 0;
  double rmse = -1;
  (void)ksvd::trainDictionary(set, tp, quiet, &rmse, [&](int, const ksvd::Dictionary& d) {
    ++iterations;
    for (int i = 0; i < m; ++i) ASSERT_EQ(d.atom(0)[i], float(1 / std::sqrt(double(m))));
    for (int a = 1; a < d.atoms; ++a) {
      double norm = 0, mean = 0;
      for (int i = 0; i < m; ++i) norm += double(d.atom(a)[i]) * d.atom(a)[i], mean += d.atom(a)[i];
      ASSERT_NEAR(norm, 1.0, 1e-4) << "atom " << a;
      ASSERT_NEAR(mean / m, 0.0, 1e-5) << "atom " << a;
    }
  });
  EXPECT_EQ(iterations, 6);
  EXPECT_GT(rmse, 0);
}

TEST(KsvdLearning, TrainingLowersTheErrorOfTheTrainingSet) {
  ksvd::TrainingSet set;
  set.m = 64;
  set.blocks = smoothBlocks(4, 800, 2);
  set.weights.assign(800, 1.0f);
  set.source.resize(800);
  ksvd::TrainParams tp;
  tp.atoms = 32, tp.sparsity = 3, tp.threads = 2;
  Progress quiet;
  double before = 0, after = 0;
  tp.iterations = 1;
  (void)ksvd::trainDictionary(set, tp, quiet, &before);
  tp.iterations = 10;
  (void)ksvd::trainDictionary(set, tp, quiet, &after);
  EXPECT_LT(after, before * 0.95) << before << " -> " << after;
}

TEST(KsvdOmp, RecoversAnExactlySparseSignalFromKnownAtoms) {
  const ksvd::Dictionary d = randomDictionary(64, 96, 3);
  const int atoms[] = {0, 17, 42, 80};
  const float coefs[] = {5.0f, 3.0f, -2.0f, 1.25f};
  std::vector<float> y(64, 0.0f);
  for (int s = 0; s < 4; ++s)
    for (int i = 0; i < 64; ++i) y[std::size_t(i)] += coefs[s] * d.atom(atoms[s])[i];
  const ksvd::SparseCode code = ksvd::ompCode(d, y, 4);
  ASSERT_EQ(code.atoms.size(), 4u);
  for (int s = 0; s < 4; ++s) {
    const auto at = std::find(code.atoms.begin(), code.atoms.end(), atoms[s]);
    ASSERT_NE(at, code.atoms.end()) << "atom " << atoms[s] << " not chosen";
    EXPECT_NEAR(code.coefficients[std::size_t(at - code.atoms.begin())], coefs[s], 1e-3);
  }
  EXPECT_EQ(code.atoms[0], 0);  // the DC atom first
  const double energy = std::inner_product(y.begin(), y.end(), y.begin(), 0.0);
  EXPECT_LT(code.residual2, 1e-6 * energy);
  // With a tolerance it stops as soon as the residual is small enough: here, after all four.
  EXPECT_EQ(ksvd::ompCode(d, y, 10, 1e-4 * energy).atoms.size(), 4u);
}

TEST(KsvdOmp, CodingErrorDoesNotGrowWithSparsity) {
  const ksvd::Dictionary d = randomDictionary(64, 128, 4);
  const std::vector<float> blocks = smoothBlocks(4, 20, 5);
  for (int b = 0; b < 20; ++b) {
    const std::span<const float> y(blocks.data() + b * 64, 64);
    double previous = std::numeric_limits<double>::infinity();
    for (int s = 1; s <= 12; ++s) {
      const ksvd::SparseCode code = ksvd::ompCode(d, y, s);
      EXPECT_LE(code.atoms.size(), std::size_t(s));
      // The residual it reports is the real one.
      std::vector<double> r(y.begin(), y.end());
      for (std::size_t k = 0; k < code.atoms.size(); ++k)
        for (int i = 0; i < 64; ++i)
          r[std::size_t(i)] -= code.coefficients[k] * d.atom(code.atoms[k])[i];
      const double real = std::inner_product(r.begin(), r.end(), r.begin(), 0.0);
      EXPECT_NEAR(code.residual2, real, 1e-3 * (1 + real));
      EXPECT_LE(code.residual2, previous * (1 + 1e-5) + 1e-9) << "block " << b << " S " << s;
      previous = code.residual2;
    }
  }
}

TEST(KsvdCoreset, WeightedStatisticsMatchTheFullSet) {
  const std::size_t n = 40000;
  const std::vector<float> blocks = smoothBlocks(4, n, 6);
  auto block = [&](std::uint64_t i, float* out) { std::copy_n(blocks.data() + i * 64, 64, out); };
  double fullEnergy = 0;
  for (std::size_t i = 0; i < n; ++i)
    for (int v = 0; v < 64; ++v) fullEnergy += double(blocks[i * 64 + v]) * blocks[i * 64 + v];
  Progress quiet;
  const ksvd::TrainingSet set = ksvd::buildCoreset(n, 64, block, 2000, 7, quiet);
  EXPECT_NEAR(double(set.count()), 2000.0, 40.0);
  double weighted = 0, weights2 = 0;
  for (std::size_t j = 0; j < set.count(); ++j) {
    for (int v = 0; v < 64; ++v) weighted += double(set.block(j)[v]) * set.block(j)[v];
    weights2 += double(set.weights[j]) * set.weights[j];
    // Blocks are stored weighted.
    float raw[64];
    block(set.source[j], raw);
    ASSERT_NEAR(set.block(j)[5], raw[5] * set.weights[j],
                1e-4f * std::abs(raw[5] * set.weights[j]) + 1e-6f);
  }
  // Sum of w^2 over the coreset estimates the number of blocks, and the weighted energy the
  // full set's energy.
  EXPECT_NEAR(weights2 / double(n), 1.0, 0.01);
  EXPECT_NEAR(weighted / fullEnergy, 1.0, 0.03);
  // Importance sampling: the coreset's blocks vary more than the full set's on average.
  auto spread = [](const float* y) {
    double s = 0, s2 = 0;
    for (int i = 0; i < 64; ++i) s += y[i], s2 += double(y[i]) * y[i];
    return std::sqrt(std::max(0.0, s2 / 64 - (s / 64) * (s / 64)));
  };
  double fullSpread = 0, pickedSpread = 0;
  for (std::size_t i = 0; i < n; ++i) fullSpread += spread(blocks.data() + i * 64);
  for (std::size_t j = 0; j < set.count(); ++j) {
    float raw[64];
    block(set.source[j], raw);
    pickedSpread += spread(raw);
  }
  EXPECT_GT(pickedSpread / double(set.count()), 1.1 * fullSpread / double(n));
}

// Pairs of every width a file may have, packed into one stream back to back (most start inside
// a byte), read back one by one; the stream is exactly the bytes its bits need.
TEST(KsvdPacking, PairsRoundTripAtTheirLimits) {
  for (int indexBits : {1, 8, 10, 16})
    for (int coefBits : {2, 7, 24 - indexBits}) {
      const int qmax = ksvd::maxQuantized(coefBits);
      EXPECT_EQ(qmax, (1 << (coefBits - 1)) - 1);
      std::vector<std::pair<int, int>> sent;
      std::vector<std::byte> stream;
      for (int atom : {0, 1, (1 << indexBits) - 1})
        for (int q : {-qmax, -1, 0, 1, qmax}) {
          const std::uint32_t word = ksvd::packPair(atom, q, indexBits, coefBits);
          ASSERT_LT(word, 1u << (indexBits + coefBits));
          ksvd::appendPair(stream, sent.size(), word, indexBits + coefBits);
          sent.emplace_back(atom, q);
        }
      EXPECT_EQ(stream.size(), (sent.size() * std::size_t(indexBits + coefBits) + 7) / 8);
      for (std::size_t i = 0; i < sent.size(); ++i) {
        int a = -1, q = 0;
        kernels::ksvdUnpack(reinterpret_cast<const std::uint8_t*>(stream.data()), i, indexBits,
                            coefBits, a, q);
        EXPECT_EQ(a, sent[i].first) << indexBits << "+" << coefBits << " pair " << i;
        EXPECT_EQ(q, sent[i].second) << indexBits << "+" << coefBits << " pair " << i;
      }
      EXPECT_THROW(ksvd::packPair(1 << indexBits, 0, indexBits, coefBits), std::invalid_argument);
      EXPECT_THROW(ksvd::packPair(0, qmax + 1, indexBits, coefBits), std::invalid_argument);
    }
  EXPECT_THROW(ksvd::packPair(0, 0, 10, 15), std::invalid_argument);  // 25 bits
  EXPECT_THROW(ksvd::packPair(0, 0, 10, 1), std::invalid_argument);
}

TEST(KsvdCodec, EmptyAndConstantBricksAreDetectedAndCostNothing) {
  // 60 x 30 x 30 at M = 6: bricks of 30^3. Brick 0 is zero, brick 1 constant 77: nothing but
  // their records; a third all-zero volume codes no block at all.
  Volume v = Volume::allocate({60, 30, 30}, ScalarType::UInt8);
  for (int z = 0; z < 30; ++z)
    for (int y = 0; y < 30; ++y)
      for (int x = 30; x < 60; ++x) v.as<std::uint8_t>()[v.index(x, y, z)] = 77;
  v.computeRange();
  Progress quiet;
  ksvd::EncodeStats s;
  auto c = ksvd::encode(v, quick(), quiet, &s);
  EXPECT_EQ(s.bricks, 2u);
  EXPECT_EQ(s.constantBricks, 2u);
  EXPECT_EQ(s.pairs, 0u);
  EXPECT_TRUE(section(c, ksvd::kPairs).empty());
  EXPECT_TRUE(std::isinf(s.psnr));
  const Volume d = ksvd::decode(c.info, c.view());
  EXPECT_EQ(d.data, v.data);
  // One voxel more in brick 1: it is coded, brick 0 stays free.
  v.as<std::uint8_t>()[v.index(40, 10, 10)] = 200;
  v.computeRange();
  c = ksvd::encode(v, quick(), quiet, &s);
  EXPECT_EQ(s.constantBricks, 1u);
  EXPECT_EQ(s.codedBlocks, 125u);
  EXPECT_GT(s.pairs, 0u);
  EXPECT_LT(s.pairs, 125u);  // blocks equal to the brick's minimum have no pairs
  const Volume d2 = ksvd::decode(c.info, c.view());
  for (int z = 0; z < 30; ++z)
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 30; ++x) ASSERT_EQ(d2.as<std::uint8_t>()[d2.index(x, y, z)], 0);
  EXPECT_GT(s.psnr, 30);
}

TEST(KsvdCodec, Float32AndInt16RoundTripWithinTheStoredPsnr) {
  Volume f = generateMarschnerLobb(30, ScalarType::Float32);
  Volume i16 = generateSheppLogan(30, ScalarType::Int16);
  for (auto& value : i16.as<std::int16_t>()) value = std::int16_t(value - 1000);  // CT-like
  i16.computeRange();
  for (const Volume* v : {&f, &i16}) {
    for (int side : {4, 6, 8}) {
      Progress quiet;
      ksvd::EncodeStats s;
      const auto c = ksvd::encode(*v, quick(side), quiet, &s);
      const ksvd::Layout layout(c.info, c.view());
      const Volume d = ksvd::decode(c.info, c.view());
      EXPECT_EQ(d.type, v->type);
      EXPECT_EQ(d.dims, v->dims);
      EXPECT_NEAR(psnr(*v, d), layout.psnr(), 1e-6) << scalarName(v->type) << " M" << side;
      EXPECT_GT(layout.psnr(), 20) << scalarName(v->type) << " M" << side;
      // Decoded values stay inside the input's range (bricks clamp to their own).
      EXPECT_GE(d.valueMin, v->valueMin);
      EXPECT_LE(d.valueMax, v->valueMax);
    }
  }
}

TEST(KsvdCodec, MoreSparsityGivesMoreQualityAndToleranceStopsEarly) {
  const Volume v = generateSheppLogan(36);
  Progress quiet;
  double previous = 0;
  for (int s : {1, 3, 8}) {
    ksvd::Params p = quick();
    p.sparsity = s;
    ksvd::EncodeStats stats;
    (void)ksvd::encode(v, p, quiet, &stats);
    EXPECT_GT(stats.psnr, previous) << "S " << s;
    EXPECT_LE(stats.pairs, stats.codedBlocks * std::uint64_t(s));
    previous = stats.psnr;
  }
  ksvd::Params loose = quick();
  loose.sparsity = 8, loose.tolerance = 0.05;
  ksvd::EncodeStats stats;
  (void)ksvd::encode(v, loose, quiet, &stats);
  EXPECT_LT(stats.pairs, stats.codedBlocks * 8);
}

TEST(KsvdCodec, BitsPerVoxelTargetIsMet) {
  const Volume v = generateMarschnerLobb(48);
  Progress quiet;
  for (double target : {1.0, 2.0}) {
    ksvd::Params p = quick();
    p.atoms = 0, p.targetBitsPerVoxel = target, p.levels = 0;  // the pyramid counts too
    ksvd::EncodeStats s;
    const auto c = ksvd::encode(v, p, quiet, &s);
    const double bpv = bitsPerVoxel(c.payloadBytes(), v);
    EXPECT_LE(bpv, target) << target;
    EXPECT_GT(bpv, 0.5 * target) << target;
  }
  ksvd::Params tiny = quick();
  tiny.targetBitsPerVoxel = 0.01;
  EXPECT_THROW(ksvd::encode(v, tiny, quiet), std::invalid_argument);
}

namespace {
// Level `level` of `v`'s pyramid as the codec documents it, computed here independently: each
// voxel the mean of the 2^level-wide cube of full-resolution voxels below it, edge-clamped per
// halving (so, per axis, halving rounds up and repeats the last voxel).
Volume boxLevel(const Volume& v, int level) {
  Volume out = Volume::allocate(v.dims, ScalarType::Float32, v.spacing);
  for (std::size_t i = 0; i < v.voxelCount(); ++i)
    out.as<float>()[i] = float(v.as<std::uint8_t>()[i]);
  for (int l = 0; l < level; ++l) {
    const glm::ivec3 d = (out.dims - 1) / 2 + 1;
    Volume next = Volume::allocate(d, ScalarType::Float32, out.spacing * 2.0);
    for (int z = 0; z < d.z; ++z)
      for (int y = 0; y < d.y; ++y)
        for (int x = 0; x < d.x; ++x) {
          double sum = 0;
          for (int k = 0; k < 2; ++k)
            for (int j = 0; j < 2; ++j)
              for (int i = 0; i < 2; ++i)
                sum += out.as<float>()[out.index(std::min(2 * x + i, out.dims.x - 1),
                                                 std::min(2 * y + j, out.dims.y - 1),
                                                 std::min(2 * z + k, out.dims.z - 1))];
          next.as<float>()[next.index(x, y, z)] = float(sum / 8);
        }
    out = std::move(next);
  }
  out.computeRange();
  return out;
}
}  // namespace

TEST(KsvdPyramid, LevelsHalveTheResolutionAndDecodeCloseToTheBoxFilteredVolume) {
  // 70^3 at M = 4 (bricks of 32 voxels): 70, 35, 18 -- the third fits in one brick.
  const Volume v = generateMarschnerLobb(70);
  Progress quiet;
  ksvd::Params p = quick(4);
  p.levels = 0;
  ksvd::EncodeStats s;
  const auto c = ksvd::encode(v, p, quiet, &s);
  EXPECT_EQ(s.levels, 3);
  EXPECT_GT(s.levelPairs, 0u);
  EXPECT_LT(s.levelPairs, s.pairs / 4);  // coarse levels are about 1/7 of the voxels
  const ksvd::Layout layout(c.info, c.view());
  ASSERT_EQ(layout.levels(), 3);
  EXPECT_EQ(layout.levelDims(1), glm::ivec3(35));
  EXPECT_EQ(layout.levelDims(2), glm::ivec3(18));
  EXPECT_DOUBLE_EQ(layout.levelPsnr(0), layout.psnr());
  for (int l = 1; l < 3; ++l) {
    const Volume reference = boxLevel(v, l);
    const Volume decoded = layout.decodeLevel(l);
    ASSERT_EQ(decoded.dims, reference.dims) << "level " << l;
    const double measured = psnr(reference, decoded);
    EXPECT_NEAR(measured, layout.levelPsnr(l), 1e-3) << "level " << l;
    EXPECT_GT(measured, 25) << "level " << l;
    // And the view samples level l at its voxel centres: (i + 1/2) 2^l - 1/2.
    const auto view = layout.view<4>();
    kernels::KsvdView<4>::RayCache rc;
    rc.footprint = float(1 << l) + 0.5f;
    const float scale = float(1 << l);
    for (glm::ivec3 q : {glm::ivec3(3, 5, 7), glm::ivec3(10, 2, 9)}) {
      const float got =
          view.sample((float(q.x) + 0.5f) * scale - 0.5f, (float(q.y) + 0.5f) * scale - 0.5f,
                      (float(q.z) + 0.5f) * scale - 0.5f, rc);
      EXPECT_NEAR(got, decoded.as<float>()[decoded.index(q.x, q.y, q.z)], 1e-3) << "level " << l;
    }
  }
  // Level 0 alone: no coarse pairs, a smaller file, the same level 0.
  p.levels = 1;
  ksvd::EncodeStats flat;
  const auto one = ksvd::encode(v, p, quiet, &flat);
  EXPECT_EQ(flat.levels, 1);
  EXPECT_EQ(flat.levelPairs, 0u);
  EXPECT_LT(one.payloadBytes(), c.payloadBytes());
  EXPECT_EQ(ksvd::Layout(one.info, one.view()).levels(), 1);
}

// A host view reads the pairs and counts where their sections lie (no copy: a rank's pages of
// them come in where its rays go), and the render buffer holds no entry per block (a block's
// first pair is summed from the counts); the joined buffer a device gets decodes every block of
// every level alike.
TEST(KsvdPyramid, TheHostViewReadsThePairsInTheirSectionAndDecodesLikeTheJoinedBuffer) {
  const Volume v = generateMarschnerLobb(40);
  Progress quiet;
  ksvd::Params p = quick(4);
  p.levels = 0;
  const auto c = ksvd::encode(v, p, quiet);
  const SectionSet sections = c.view();
  const auto pairs = sections.get(ksvd::kPairs, "pairs");
  ASSERT_FALSE(pairs.empty());
  const ksvd::Layout layout(c.info, sections);
  ASSERT_GT(layout.levels(), 1);
  const auto counts = sections.get(ksvd::kCounts, "counts");
  ASSERT_FALSE(counts.empty());
  const std::vector<std::byte> joined = layout.joinedBytes();
  EXPECT_GE(joined.size(), layout.renderBufferBytes() + pairs.size() + counts.size());
  // Atoms as floats and a 32-byte record per brick, aligned: nothing that grows with the blocks.
  EXPECT_LE(layout.renderBufferBytes(),
            std::uint64_t(layout.atoms()) * 64 * 4 + layout.bricks() * 32 + 16);
  const auto host = layout.view<4>();
  const auto device = layout.view<4>(joined.data());
  int blocks = 0;
  for (int l = 0; l < layout.levels(); ++l) {
    const auto& h = host.level[l].decoder;
    const auto& d = device.level[l].decoder;
    EXPECT_EQ(static_cast<const void*>(h.pairs.data), static_cast<const void*>(pairs.data()));
    EXPECT_EQ(static_cast<const void*>(h.counts.data), static_cast<const void*>(counts.data()));
    EXPECT_EQ(static_cast<const void*>(h.dc.data),
              static_cast<const void*>(sections.get(ksvd::kDc, "dc").data()));
    for (int bz = 0; bz < (layout.levelDims(l).z + 3) / 4; ++bz)
      for (int by = 0; by < (layout.levelDims(l).y + 3) / 4; ++by)
        for (int bx = 0; bx < (layout.levelDims(l).x + 3) / 4; ++bx, ++blocks) {
          float a[64], b[64];
          h.decode(h.key(bx, by, bz), a);
          d.decode(d.key(bx, by, bz), b);
          for (int i = 0; i < 64; ++i)
            ASSERT_EQ(a[i], b[i]) << "level " << l << " block " << bx << "," << by << "," << bz;
        }
  }
  EXPECT_GT(blocks, 1000);
}

TEST(KsvdPyramid, FilesWithoutTheLevelsSectionReadAsOneLevel) {
  // Files written before the pyramid have no section 6: level 0 alone.
  const Volume v = generateSheppLogan(40);
  Progress quiet;
  auto c = ksvd::encode(v, quick(4), quiet);
  const Volume before = ksvd::decode(c.info, c.view());
  std::erase_if(c.sections, [](const auto& s) { return s.first == ksvd::kLevels; });
  const ksvd::Layout layout(c.info, c.view());
  EXPECT_EQ(layout.levels(), 1);
  EXPECT_EQ(layout.decode().data, before.data);
}

// Files written before the coefficient's width was stored end their params at the PSNR and hold
// 3-byte pairs (in layout 1): the same bits as a stored width of 24 less the index's.
TEST(KsvdCodec, FilesWithoutTheCoefficientWidthReadAsThreeBytePairs) {
  const Volume v = generateSheppLogan(40);
  Progress quiet;
  auto c = test::asKsvdLayout1(ksvd::encode(v, quick(4), quiet));
  const ksvd::Layout stored(c.info, c.view());
  const int indexBits = 5;  // quick(): 32 atoms
  ASSERT_EQ(stored.atoms(), 32);
  ASSERT_EQ(stored.coefficientBits(), 24 - indexBits);
  EXPECT_EQ(section(c, ksvd::kPairs).size(), 3 * stored.pairs());
  const Volume before = stored.decode();
  section(c, ksvd::kParams).resize(64);
  const ksvd::Layout old(c.info, c.view());
  EXPECT_EQ(old.coefficientBits(), 24 - indexBits);
  EXPECT_EQ(old.decode().data, before.data);
}

// Narrower coefficients make a smaller pair stream of the same pairs' atoms, and the decoder
// reads them at any width: each width's file decodes to what its encoder measured.
TEST(KsvdCodec, NarrowCoefficientsPackThePairsTighter) {
  const Volume v = generateMarschnerLobb(40);
  Progress quiet;
  ksvd::Params wide = quick(4);
  ksvd::Params narrow = wide;
  narrow.coefficientBits = 6;
  ksvd::EncodeStats ws, ns;
  const auto w = ksvd::encode(v, wide, quiet, &ws);
  const auto n = ksvd::encode(v, narrow, quiet, &ns);
  EXPECT_EQ(ns.coefficientBits, 6);
  EXPECT_EQ(ws.coefficientBits, 24 - ns.indexBits);
  EXPECT_EQ(ns.pairBytes, (ns.pairs * std::uint64_t(ns.indexBits + 6) + 7) / 8);
  EXPECT_LT(ns.pairBytes, ws.pairBytes * 12 / 24 + 1);
  EXPECT_LT(ns.psnr, ws.psnr);  // coarser coefficients
  EXPECT_GT(ns.psnr, 20.0);
  const ksvd::Layout layout(n.info, n.view());
  EXPECT_EQ(layout.coefficientBits(), 6);
  EXPECT_NEAR(psnr(v, layout.decode()), ns.psnr, 1e-9);
  ksvd::Params tooWide = wide;
  tooWide.coefficientBits = 20;  // 5 index bits + 20 > 24
  try {
    (void)ksvd::encode(v, tooWide, quiet);
    ADD_FAILURE() << "a 25-bit pair was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--coefficient-bits 20 leaves no room"), std::string::npos)
        << e.what();
  }
}

// Through the registry, at a size target.
CompressedVolume encodeAt(const Volume& v, double bits, int block, int coefficientBits,
                          std::string& report) {
  CodecOptionValues o;
  o.set("--bits-per-voxel", std::to_string(bits));
  o.set("--iterations", "2"), o.set("--levels", "1");
  if (block) o.set("--block", std::to_string(block));
  if (coefficientBits) o.set("--coefficient-bits", std::to_string(coefficientBits));
  Progress quiet;
  return codecNamed("ksvd").encode(v, o, quiet, report);
}

// A size target without --block codes blocks of 4^3 and of 6^3 and keeps the higher PSNR; where
// blocks of 4^3 cannot meet the target (their means alone are 5 bits and their counts a bit per
// block: noise, no constant bricks), 6^3, and the report says why. A --block that cannot meet
// the target is refused. (--coefficient-bits pins the width, searched in the next test.)
TEST(KsvdCodec, SizeTargetsKeepTheBetterBlockSide) {
  Volume noise = Volume::allocate({80, 80, 80}, ScalarType::Float32);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  for (float& x : noise.as<float>()) x = uniform(rng);
  noise.computeRange();
  std::string report;
  const auto fellBack = encodeAt(noise, 0.15, 0, 6, report);
  const ksvd::Layout six(fellBack.info, fellBack.view());
  EXPECT_EQ(six.blockSide(), 6);
  EXPECT_EQ(six.coefficientBits(), 6);
  EXPECT_EQ(six.meanBits(), 5);
  EXPECT_NE(report.find("blocks of 6^3, since --bits-per-voxel 0.15 is below the smallest ksvd "
                        "file of this volume with "),
            std::string::npos)
      << report;
  EXPECT_NE(report.find("and blocks of 4^3"), std::string::npos) << report;
  EXPECT_THROW(encodeAt(noise, 0.15, 4, 0, report), ksvd::SizeTargetTooSmall);

  const Volume phantom = generateSheppLogan(80);
  std::string r4, r6;
  const auto four = encodeAt(phantom, 0.5, 4, 7, r4), sixOnly = encodeAt(phantom, 0.5, 6, 7, r6);
  const double psnr4 = ksvd::Layout(four.info, four.view()).psnr();
  const double psnr6 = ksvd::Layout(sixOnly.info, sixOnly.view()).psnr();
  ASSERT_NE(psnr4, psnr6);
  const auto best = encodeAt(phantom, 0.5, 0, 7, report);
  const ksvd::Layout kept(best.info, best.view());
  EXPECT_EQ(kept.blockSide(), psnr4 > psnr6 ? 4 : 6);
  EXPECT_EQ(kept.psnr(), std::max(psnr4, psnr6));
  EXPECT_NE(report.find("both coded, --block codes one"), std::string::npos) << report;
  EXPECT_EQ(report.find("--coefficient-bits codes one"), std::string::npos) << report;
}

// Without --coefficient-bits, a size target codes the kept block side again with coefficients one
// bit wider than the rate's width (6 below 0.35 bits per voxel, 7 below 0.75) and keeps the
// higher PSNR, in the target.
TEST(KsvdCodec, SizeTargetsTryCoefficientsOneBitWider) {
  const Volume phantom = generateSheppLogan(80);
  for (const auto& [bits, width] : {std::pair{0.5, 7}, std::pair{0.3, 6}}) {
    SCOPED_TRACE(bits);
    std::string report;
    const auto narrow = encodeAt(phantom, bits, 4, width, report);
    const auto wide = encodeAt(phantom, bits, 4, width + 1, report);
    const double psnrNarrow = ksvd::Layout(narrow.info, narrow.view()).psnr();
    const double psnrWide = ksvd::Layout(wide.info, wide.view()).psnr();
    ASSERT_NE(psnrNarrow, psnrWide);
    const auto searched = encodeAt(phantom, bits, 4, 0, report);
    const ksvd::Layout kept(searched.info, searched.view());
    EXPECT_EQ(kept.coefficientBits(), psnrWide > psnrNarrow ? width + 1 : width);
    EXPECT_EQ(kept.meanBits(), kept.coefficientBits() - 1);
    EXPECT_EQ(kept.psnr(), std::max(psnrNarrow, psnrWide));
    EXPECT_LE(bitsPerVoxel(searched.payloadBytes(), phantom), bits);
    const bool wider = psnrWide > psnrNarrow;
    const std::string line = formatLine(
        "coefficients of %d bits (PSNR %.2f dB) over coefficients of %d bits (%.2f dB): both "
        "coded, --coefficient-bits codes one",
        wider ? width + 1 : width, std::max(psnrNarrow, psnrWide), wider ? width : width + 1,
        std::min(psnrNarrow, psnrWide));
    EXPECT_NE(report.find(line), std::string::npos) << report;
    // Both searches: the side's line, then the width's.
    encodeAt(phantom, bits, 0, 0, report);
    const std::size_t side = report.find("--block codes one");
    EXPECT_NE(side, std::string::npos) << report;
    EXPECT_GT(report.find("--coefficient-bits codes one"), side) << report;
  }
}

// A size target leaving about one pair per block on average still trains with two: the DC atom
// is every block's first pair, so training with one would never use a learned atom.
TEST(KsvdCodec, ATightSizeTargetTrainsWithAtLeastTwoPairsPerBlock) {
  const Volume v = generateSheppLogan(80);
  Progress quiet;
  ksvd::Params p = quick(4);
  p.sparsity = 16;
  p.targetBitsPerVoxel = 0.3;
  ksvd::EncodeStats s;
  (void)ksvd::encode(v, p, quiet, &s);
  ASSERT_GT(s.codedBlocks, 0u);
  ASSERT_LT(double(s.pairs) / double(s.codedBlocks), 1.5);  // the budget's average rounds to 1
  EXPECT_EQ(s.trainSparsity, 2);
}

TEST(KsvdCodec, RefusesBadParameters) {
  const Volume v = generateMenger(2);
  Progress quiet;
  auto refused = [&](auto change) {
    ksvd::Params p = quick();
    change(p);
    EXPECT_THROW(ksvd::encode(v, p, quiet), std::invalid_argument);
  };
  refused([](ksvd::Params& p) { p.blockSide = 5; });
  refused([](ksvd::Params& p) { p.atoms = 1; });
  refused([](ksvd::Params& p) { p.sparsity = 0; });
  refused([](ksvd::Params& p) { p.tolerance = -0.1; });
  refused([](ksvd::Params& p) { p.levels = 9; });
  refused([](ksvd::Params& p) { p.coefficientBits = 1; });
  refused([](ksvd::Params& p) { p.coefficientBits = 24; });
  refused([](ksvd::Params& p) { p.meanBits = 25; });
  Volume nan = Volume::allocate({8, 8, 8}, ScalarType::Float32);
  nan.as<float>()[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(ksvd::encode(nan, quick(), quiet), std::invalid_argument);
}

// ---- corrupt sections -------------------------------------------------------------------

namespace {
CompressedVolume small() {
  Progress quiet;
  ksvd::Params p = quick();
  p.atoms = 12, p.sparsity = 4, p.iterations = 2;  // 4 index bits, atoms 12..15 unused
  return ksvd::encode(generateSheppLogan(20), p, quiet);
}
void expectKsvdRefused(const CompressedVolume& c, const std::string& fragment) {
  test::expectFormatError([&] { ksvd::Layout(c.info, c.view("bad.vwz")); }, "bad.vwz", fragment);
}
// The offset of the first coded brick's record in the bricks section.
std::size_t firstCodedBrick(CompressedVolume& c) {
  const auto& b = section(c, ksvd::kBricks);
  for (std::size_t at = 0; at < b.size(); at += 16) {
    std::uint32_t index;
    std::memcpy(&index, b.data() + at + 12, 4);
    if (index != 0xFFFFFFFFu) return at;
  }
  throw std::logic_error("no coded brick");
}
}  // namespace

TEST(KsvdCorrupt, BadSectionsAreRefusedWithTheirName) {
  {
    auto c = small();
    section(c, ksvd::kParams).resize(20);
    expectKsvdRefused(c, "section 'params': truncated");
  }
  // A u32 of the params at its offset, and what the refusal says.
  const struct {
    std::size_t at;
    std::uint32_t value;
    const char* says;
  } params[] = {{0, 5, "block side 5"},         {8, 1, "atoms 1"},
                {12, 0, "sparsity 0"},          {16, 9, "index bits 9 for 12 atoms"},
                {68, 3, "layout 3 (1 or 2)"},   {72, 0, "mean bits 0 (1..24)"},
                {76, 3, "atom bits 3 (4..16)"}, {76, 17, "atom bits 17 (4..16)"}};
  for (const auto& p : params) {
    auto c = small();
    poke<std::uint32_t>(section(c, ksvd::kParams), p.at, p.value);
    expectKsvdRefused(c, p.says);
  }
  {
    auto c = small();
    poke<std::uint32_t>(section(c, ksvd::kParams), 64, 21);  // 4 + 21 bits: over 3 bytes
    expectKsvdRefused(c, "coefficient bits 21 with 4 index bits");
    poke<std::uint32_t>(section(c, ksvd::kParams), 64, 1);
    expectKsvdRefused(c, "coefficient bits 1 with 4 index bits");
  }
  {
    auto c = small();
    section(c, ksvd::kParams).resize(84);
    expectKsvdRefused(c, "4 bytes past the params");
  }
  {
    auto c = small();
    section(c, ksvd::kDictionary).pop_back();
    expectKsvdRefused(c, "section 'dictionary'");
    c = small();
    poke<float>(section(c, ksvd::kDictionary), 4, std::numeric_limits<float>::quiet_NaN());
    expectKsvdRefused(c, "section 'dictionary': atom 1 has a scale of");
  }
  {
    auto c = small();
    section(c, ksvd::kBricks).resize(8);
    expectKsvdRefused(c, "section 'bricks'");
  }
  {
    auto c = small();
    const std::size_t at = firstCodedBrick(c);
    poke<float>(section(c, ksvd::kBricks), at, 1e30f);  // min above max
    expectKsvdRefused(c, "bad value range");
  }
  {
    auto c = small();
    const std::size_t at = firstCodedBrick(c);
    poke<float>(section(c, ksvd::kBricks), at + 8, std::numeric_limits<float>::quiet_NaN());
    expectKsvdRefused(c, "bad coefficient step");
  }
  {
    auto c = small();
    poke<std::uint32_t>(section(c, ksvd::kBricks), firstCodedBrick(c) + 12, 7);
    expectKsvdRefused(c, "coded index 7");
  }
  {
    auto c = small();  // a run of ones longer than S - 1 pairs
    for (std::byte& b : section(c, ksvd::kCounts)) b = std::byte{0xFF};
    expectKsvdRefused(c, "has 4 pairs besides its mean (0..3)");
  }
  {
    auto c = small();
    section(c, ksvd::kCounts).push_back(std::byte{0});
    expectKsvdRefused(c, "section 'counts'");
  }
  {
    auto c = small();
    section(c, ksvd::kDc).pop_back();
    expectKsvdRefused(c, "section 'dc'");
  }
  {
    auto c = test::asKsvdLayout1(small());
    section(c, ksvd::kCounts)[0] = std::byte{200};
    expectKsvdRefused(c, "has 200 pairs");
  }
  {
    auto c = small();
    auto& p = section(c, ksvd::kPairs);
    p[0] |= std::byte{0x0F};  // atom 15 of 12
    expectKsvdRefused(c, "names atom 15 of 12");
  }
  {
    auto c = small();
    section(c, ksvd::kPairs).resize(section(c, ksvd::kPairs).size() - 3);
    expectKsvdRefused(c, "section 'pairs'");
  }
  {
    auto c = small();
    poke<std::uint64_t>(section(c, ksvd::kParams), 24, std::uint64_t(1) << 60);
    expectKsvdRefused(c, "coded bricks of");
  }
  {
    auto c = small();
    poke<std::uint32_t>(section(c, ksvd::kLevels), 0, 9);
    expectKsvdRefused(c, "levels 9 (1..8)");
  }
  {
    auto c = small();
    poke<std::uint32_t>(section(c, ksvd::kLevels), 0, 0);
    expectKsvdRefused(c, "levels 0 (1..8)");
  }
  {
    // Two levels announced, one level's PSNR and bricks present.
    auto c = small();
    section(c, ksvd::kLevels).resize(20);
    poke<std::uint32_t>(section(c, ksvd::kLevels), 0, 2);
    expectKsvdRefused(c, "section 'bricks'");
    section(c, ksvd::kLevels).resize(12);
    expectKsvdRefused(c, "section 'levels'");
  }
  {
    auto c = small();
    poke<double>(section(c, ksvd::kLevels), 4, std::numeric_limits<double>::quiet_NaN());
    expectKsvdRefused(c, "PSNR is not a number");
  }
  auto c = small();
  std::erase_if(c.sections, [](const auto& s) { return s.first == ksvd::kPairs; });
  expectKsvdRefused(c, "missing section");
}

// A hostile file whose coefficients overflow a float: every decoded voxel stays inside its
// brick's range (never NaN or infinite), so nothing downstream converts a NaN to an integer.
TEST(KsvdCorrupt, OverflowingCoefficientsDecodeInsideTheBricksRange) {
  auto c = small();
  const std::size_t at = firstCodedBrick(c);
  float lo, hi;
  std::memcpy(&lo, section(c, ksvd::kBricks).data() + at, 4);
  std::memcpy(&hi, section(c, ksvd::kBricks).data() + at + 4, 4);
  poke<float>(section(c, ksvd::kBricks), at + 8, 3e38f);  // a finite but enormous step
  c.info.type = ScalarType::Float32;
  const ksvd::Layout layout(c.info, c.view());
  const auto view = layout.view<6>();
  // Every block of the (single) brick, some of them with pairs.
  int withPairs = 0;
  for (std::byte bits : section(c, ksvd::kCounts)) withPairs += bits != std::byte{0};
  ASSERT_GT(withPairs, 0);
  for (std::uint64_t b = 0; b < 4 * 4 * 4; ++b) {
    float block[216];
    view.level[0].decoder.decode(b, block);
    for (float v : block) {
      ASSERT_TRUE(std::isfinite(v)) << "block " << b;
      ASSERT_GE(v, lo);
      ASSERT_LE(v, hi);
    }
  }
}

// Whole bricks on the host (the reference of the device decompressor, ksvd_device_test.cpp):
// level 0's bricks hold the decoded volume's voxels, coarser levels' the decoded level's, and
// positions past a level's edge are 0.
TEST(KsvdBricks, DecompressedBricksHoldTheDecodedLevels) {
  const Volume v = generateMarschnerLobb(45, ScalarType::Float32);
  for (int side : {4, 6}) {
    ksvd::Params p = quick(side);
    p.levels = 2;
    Progress quiet;
    const auto c = ksvd::encode(v, p, quiet);
    const ksvd::Layout layout(c.info, c.view());
    const int w = side * ksvd::blocksPerBrick(side);  // 32 or 30 voxels: 2 bricks a side
    for (int level : {0, 1}) {
      const Volume decoded = level ? layout.decodeLevel(1) : layout.decode();
      const glm::ivec3 grid = layout.levelBricks(level);
      ASSERT_EQ(grid, (decoded.dims + w - 1) / w);
      std::vector<ksvd::BrickRef> bricks;
      for (int z = 0; z < grid.z; ++z)
        for (int y = 0; y < grid.y; ++y)
          for (int x = 0; x < grid.x; ++x) bricks.push_back({level, {x, y, z}});
      const std::vector<float> out = ksvd::decompressBricks(layout, bricks);
      ASSERT_EQ(out.size(), bricks.size() * std::size_t(w * w * w));
      for (std::size_t i = 0; i < bricks.size(); ++i)
        for (int z = 0; z < w; ++z)
          for (int y = 0; y < w; ++y)
            for (int x = 0; x < w; ++x) {
              const glm::ivec3 at = bricks[i].brick * w + glm::ivec3(x, y, z);
              const float got = out[i * std::size_t(w * w * w) + std::size_t((z * w + y) * w + x)];
              const bool inside =
                  at.x < decoded.dims.x && at.y < decoded.dims.y && at.z < decoded.dims.z;
              ASSERT_EQ(got, inside ? decoded.as<float>()[decoded.index(at.x, at.y, at.z)] : 0.0f)
                  << "M" << side << " level " << level << " voxel " << at.x << "," << at.y << ","
                  << at.z;
            }
    }
    const ksvd::BrickRef outside{0, {5, 0, 0}}, noLevel{2, {0, 0, 0}};
    EXPECT_THROW(ksvd::decompressBricks(layout, std::span(&outside, 1)), std::invalid_argument);
    EXPECT_THROW(ksvd::decompressBricks(layout, std::span(&noLevel, 1)), std::invalid_argument);
  }
}

// The two phases of the device decompressor (pairs, then voxels), run here one thread after the
// other, give the block decoder's values for every block of every level and block side.
TEST(KsvdBricks, TwoPhaseDecodeEqualsTheBlockDecoder) {
  const Volume v = generateMarschnerLobb(40, ScalarType::Float32);
  for (int side : {4, 6, 8}) {
    ksvd::Params p = quick(side);
    p.levels = 2;
    Progress quiet;
    const auto c = ksvd::encode(v, p, quiet);
    const ksvd::Layout layout(c.info, c.view());
    std::size_t blocks = 0;
    layout.withView([&](const auto& view) {
      for (int l = 0; l < view.levels; ++l) {
        const auto& d = view.level[l].decoder;
        constexpr int kVoxels = std::decay_t<decltype(d)>::kVoxels;
        const int blocksZ = (view.level[l].dimZ + side - 1) / side;
        for (int bz = 0; bz < blocksZ; ++bz)
          for (int by = 0; by < d.blocksY; ++by)
            for (int bx = 0; bx < d.blocksX; ++bx, ++blocks) {
              const std::uint64_t key = d.key(bx, by, bz);
              float expected[kVoxels];
              d.decode(key, expected);
              const auto code = d.locate(key);
              int atom[255];
              float coefficient[255];
              for (int t = 0; t < code.count; ++t) d.pairOf(code, t, atom[t], coefficient[t]);
              for (int i = 0; i < kVoxels; ++i)
                ASSERT_NEAR(d.voxelOf(code, atom, coefficient, i), expected[i], 1e-5)
                    << "M" << side << " level " << l << " block " << bx << "," << by << "," << bz;
            }
      }
    });
    EXPECT_GT(blocks, 0u);
  }
}

// A raw file read a row of bricks at a time gives the file of the same volume held in memory,
// byte for byte: three rows of level-0 bricks and a pyramid, each block side, integer and float
// data, and a size target's search (a coding pass per tolerance it tries).
TEST(KsvdCodec, AVolumeReadInSlabsGivesTheFileOfTheVolumeInMemory) {
  voxwall::test::TempDir dir;
  Progress quiet;
  struct Case {
    Volume v;
    int side;
    double bitsPerVoxel;
  };
  std::vector<Case> cases;
  cases.push_back({generateSheppLogan(70), 4, 0});
  cases.push_back({generateMarschnerLobb(70, ScalarType::Float32), 6, 0});
  cases.push_back({generateSheppLogan(70, ScalarType::Int16), 8, 0});
  cases.push_back({generateSheppLogan(70), 4, 0.8});
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(scalarName(c.v.type)) + " block " + std::to_string(c.side));
    const std::string path = dir.path("v" + std::to_string(&c - cases.data()) + ".raw");
    writeRaw(c.v, path);
    RawLayout layout;
    layout.dims = c.v.dims, layout.type = c.v.type, layout.spacing = c.v.spacing;
    const auto source = openVolumeSource(path, layout, quiet);
    ASSERT_TRUE(source->streams());
    ksvd::Params p = quick(c.side);
    p.levels = 0;
    p.targetBitsPerVoxel = c.bitsPerVoxel;
    ksvd::EncodeStats fromMemory, fromFile;
    const auto a = ksvd::encode(c.v, p, quiet, &fromMemory);
    const auto b = ksvd::encode(*source, p, quiet, &fromFile);
    EXPECT_GT(fromFile.levels, 1);
    EXPECT_GT(fromFile.bricks - fromFile.constantBricks, 3u);
    EXPECT_EQ(serializeContainer(a), serializeContainer(b));
    EXPECT_EQ(fromMemory.psnr, fromFile.psnr);
  }
}
