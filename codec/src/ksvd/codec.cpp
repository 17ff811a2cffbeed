// The ksvd codec: encoder, layout and decoder; the byte layout is documented in ksvd_codec.hpp.
#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/common.hpp>
#include <limits>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>

#include "learning.hpp"

namespace voxwall::codec::ksvd {
namespace {

constexpr std::uint32_t kConstant = 0xFFFFFFFFu;
constexpr std::uint64_t kDefaultCoreset = 32768;  // training blocks when --coreset is not given
constexpr int kMaxAtoms = 1 << 16;

int indexBitsFor(int atoms) { return std::max(1, int(std::bit_width(unsigned(atoms - 1)))); }

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// The bricking of a volume: blocks of M^3 voxels, bricks of N^3 blocks.
struct Grid {
  int m = 6, n = 5;
  glm::ivec3 dims{}, blocks{}, bricks{};
  Grid(glm::ivec3 d, int side) : m(side), n(ksvd::blocksPerBrick(side)), dims(d) {
    blocks = (dims + m - 1) / m;
    bricks = (blocks + n - 1) / n;
  }
  std::uint64_t brickCount() const {
    return std::uint64_t(bricks.x) * std::uint64_t(bricks.y) * std::uint64_t(bricks.z);
  }
  std::uint64_t blockCount() const {
    return std::uint64_t(blocks.x) * std::uint64_t(blocks.y) * std::uint64_t(blocks.z);
  }
  int blocksPerBrick() const { return n * n * n; }
  glm::ivec3 brickCoords(std::uint64_t b) const {
    return {int(b % std::uint64_t(bricks.x)),
            int(b / std::uint64_t(bricks.x) % std::uint64_t(bricks.y)),
            int(b / (std::uint64_t(bricks.x) * std::uint64_t(bricks.y)))};
  }
  // Block j (x fastest) of a brick, in block coordinates; may lie outside the block grid.
  glm::ivec3 blockOf(glm::ivec3 brick, int j) const {
    return brick * n + glm::ivec3{j % n, (j / n) % n, j / (n * n)};
  }
  bool inGrid(glm::ivec3 b) const { return b.x < blocks.x && b.y < blocks.y && b.z < blocks.z; }
};

template <class T>
struct Source {
  std::span<const T> data;
  glm::ivec3 dims;
  float at(int x, int y, int z) const {
    x = std::min(x, dims.x - 1), y = std::min(y, dims.y - 1), z = std::min(z, dims.z - 1);
    return float(
        data[(std::size_t(z) * std::size_t(dims.y) + std::size_t(y)) * std::size_t(dims.x) +
             std::size_t(x)]);
  }
  // Block b's voxels (edge-padded), minus `lo`, divided by `scale`.
  void block(glm::ivec3 b, int m, float lo, float scale, float* out) const {
    const float inv = 1.0f / scale;
    for (int z = 0, i = 0; z < m; ++z)
      for (int y = 0; y < m; ++y)
        for (int x = 0; x < m; ++x, ++i)
          out[i] = (at(b.x * m + x, b.y * m + y, b.z * m + z) - lo) * inv;
  }
};

struct BrickRecord {
  float lo = 0, hi = 0, step = 0;
  std::uint32_t coded = kConstant;
};

template <class T>
CompressedVolume encodeTyped(const Volume& volume, const Params& params, Progress& progress,
                             EncodeStats& stats) {
  const Grid g(volume.dims, params.blockSide);
  const int m = g.m * g.m * g.m, perBrick = g.blocksPerBrick();
  const Source<T> src{volume.as<T>(), volume.dims};
  // The value range: the scale blocks are coded in, and the tolerance's unit.
  float vmin = std::numeric_limits<float>::infinity(), vmax = -vmin;
  for (T v : src.data) {
    if (!std::isfinite(float(v)))
      throw std::invalid_argument("ksvd codec: the volume holds NaN or infinite values");
    vmin = std::min(vmin, float(v)), vmax = std::max(vmax, float(v));
  }
  const float scale = vmax > vmin ? vmax - vmin : 1.0f;
  const double tolerance = params.tolerance;

  // Bricks: value ranges; constant bricks keep their mean.
  const std::uint64_t nBricks = g.brickCount();
  std::vector<BrickRecord> bricks(nBricks);
  progress.begin("bricking", nBricks);
  parallelFor(std::size_t(nBricks), params.threads, [&](std::size_t b) {
    const glm::ivec3 bc = g.brickCoords(b);
    const glm::ivec3 lo = bc * g.n * g.m, hi = glm::min(lo + g.n * g.m, g.dims);
    float l = std::numeric_limits<float>::infinity(), h = -l;
    double sum = 0;
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) {
          const float v = src.at(x, y, z);
          l = std::min(l, v), h = std::max(h, v), sum += v;
        }
    BrickRecord& r = bricks[b];
    if (double(h) - double(l) <= tolerance * double(scale)) {
      const double count = double(hi.x - lo.x) * double(hi.y - lo.y) * double(hi.z - lo.z);
      r.lo = r.hi = h == l ? l : float(sum / count);
    } else {
      r.lo = l, r.hi = h;
    }
    progress.advance();
  });
  progress.end();
  std::vector<std::uint64_t> coded;  // brick indices of the coded bricks
  for (std::uint64_t b = 0; b < nBricks; ++b)
    if (bricks[b].lo != bricks[b].hi)
      bricks[b].coded = std::uint32_t(coded.size()), coded.push_back(b);
  if (coded.size() >= kConstant) throw std::invalid_argument("ksvd codec: too many bricks");
  // The candidate blocks: every in-grid block of every coded brick, in brick order.
  std::vector<std::uint64_t> candidates;  // coded-brick index * perBrick + j
  for (std::size_t c = 0; c < coded.size(); ++c) {
    const glm::ivec3 bc = g.brickCoords(coded[c]);
    for (int j = 0; j < perBrick; ++j)
      if (g.inGrid(g.blockOf(bc, j))) candidates.push_back(std::uint64_t(c) * perBrick + j);
  }
  auto candidateBlock = [&](std::uint64_t i, float* out) {
    const std::uint64_t c = candidates[std::size_t(i)] / std::uint64_t(perBrick);
    const int j = int(candidates[std::size_t(i)] % std::uint64_t(perBrick));
    const std::uint64_t b = coded[std::size_t(c)];
    src.block(g.blockOf(g.brickCoords(b), j), g.m, bricks[b].lo, scale, out);
  };

  // Dictionary size, sparsity and training-set size.
  const std::uint64_t fixedBytes =
      nBricks * 16 + std::uint64_t(coded.size()) * std::uint64_t(perBrick) + 128;
  int atoms = params.atoms;
  if (atoms == 0) {  // the default: 1024, at most one atom per 16 coded blocks, at least 16
    atoms = int(std::clamp<std::uint64_t>(candidates.size() / 16, 16, 1024));
    if (params.targetBitsPerVoxel > 0) {  // and the dictionary at most a quarter of the file
      const double budget = params.targetBitsPerVoxel * double(volume.voxelCount()) / 8.0;
      while (atoms > 16 && double(atoms) * m * 2 > budget / 4) atoms /= 2;
    }
  }
  int sparsity = std::min(params.sparsity, m);
  // Training codes blocks with the sparsity the file will have on average: S, or with a size
  // target the pairs per block the budget leaves after the dictionary and the tables.
  int trainSparsity = sparsity;
  if (params.targetBitsPerVoxel > 0 && !candidates.empty()) {
    const double budget = params.targetBitsPerVoxel * double(volume.voxelCount()) / 8.0;
    const double perBlock =
        (budget - double(fixedBytes) - double(atoms) * m * 2) / (3.0 * double(candidates.size()));
    trainSparsity = int(std::clamp(std::lround(perBlock), 1l, long(sparsity)));
  }
  sparsity = std::max(1, std::min(sparsity, 255));
  std::uint64_t coresetSize = kDefaultCoreset;
  if (params.coreset > 1)
    coresetSize = std::uint64_t(params.coreset);
  else if (params.coreset > 0)
    coresetSize = std::uint64_t(std::ceil(params.coreset * double(candidates.size())));
  coresetSize = std::min<std::uint64_t>(coresetSize, candidates.size());

  // Learning.
  Dictionary dict;
  dict.m = m;
  auto start = std::chrono::steady_clock::now();
  if (!candidates.empty()) {
    const TrainingSet set =
        buildCoreset(candidates.size(), m, candidateBlock, coresetSize, params.seed, progress);
    atoms = std::max(2, std::min<int>(atoms, int(std::max<std::size_t>(set.count(), 2))));
    TrainParams tp;
    tp.atoms = atoms, tp.sparsity = trainSparsity, tp.iterations = params.iterations;
    tp.threads = params.threads, tp.seed = params.seed;
    dict = trainDictionary(set, tp, progress, &stats.trainingRmse);
    stats.coreset = set.count();
  } else {  // nothing to code: the DC atom and one more, so the file stays well-formed
    atoms = 2;
    dict.atoms = 2;
    dict.values.assign(std::size_t(2 * m), 0.0f);
    for (int i = 0; i < m; ++i)
      dict.values[std::size_t(i)] = float(1 / std::sqrt(double(m))),
      dict.values[std::size_t(m + i)] = float((i & 1 ? 1 : -1) / std::sqrt(double(m)));
  }
  stats.trainSeconds = seconds(start);
  // What the file stores is the 16-bit dictionary; code against exactly that.
  std::vector<std::int16_t> stored(dict.values.size());
  for (std::size_t i = 0; i < stored.size(); ++i)
    stored[i] = std::int16_t(std::lround(std::clamp(dict.values[i], -1.0f, 1.0f) * 32767.0f));
  for (std::size_t i = 0; i < stored.size(); ++i) dict.values[i] = float(stored[i]) / 32767.0f;
  const int indexBits = indexBitsFor(atoms);
  const int qmax = maxQuantized(indexBits);

  // Coding: every block of every coded brick, brick by brick, at a per-block tolerance.
  start = std::chrono::steady_clock::now();
  const Coder coder(dict);
  struct Coded {
    std::vector<std::vector<std::uint8_t>> counts, pairs;
    std::vector<float> steps;  // per coded brick, in value units
    std::uint64_t pairCount = 0;
  };
  auto codeAt = [&](double blockTolerance, const char* stage) {
    const double maxResidual2 = blockTolerance * blockTolerance * double(m);
    Coded out;
    out.counts.resize(coded.size()), out.pairs.resize(coded.size());
    out.steps.resize(coded.size());
    progress.begin(stage, candidates.size());
    parallelFor(coded.size(), params.threads, [&](std::size_t c) {
      const std::uint64_t b = coded[c];
      const glm::ivec3 bc = g.brickCoords(b);
      std::vector<float> y(std::size_t(perBrick) * std::size_t(m));
      std::vector<int> inGrid;
      for (int j = 0; j < perBrick; ++j)
        if (g.inGrid(g.blockOf(bc, j))) {
          src.block(g.blockOf(bc, j), g.m, bricks[b].lo, scale,
                    y.data() + inGrid.size() * std::size_t(m));
          inGrid.push_back(j);
        }
      std::vector<SparseCode> codes;
      codeAll(coder, y.data(), inGrid.size(), sparsity, maxResidual2, 1, codes);
      float maxAbs = 0;
      for (const SparseCode& code : codes)
        for (float v : code.coefficients) maxAbs = std::max(maxAbs, std::abs(v));
      const float step = maxAbs > 0 ? maxAbs / float(qmax) : 1.0f / float(qmax);
      out.steps[c] = step * scale;
      std::vector<std::uint8_t>& counts = out.counts[c];
      std::vector<std::uint8_t>& pairs = out.pairs[c];
      counts.assign(std::size_t(perBrick), 0);
      for (std::size_t i = 0; i < inGrid.size(); ++i) {
        const SparseCode& code = codes[i];
        int count = 0;
        for (std::size_t s = 0; s < code.atoms.size(); ++s) {
          const int q = std::clamp(int(std::lround(code.coefficients[s] / step)), -qmax, qmax);
          if (q == 0) continue;  // adds nothing: a block equal to its brick's minimum has none
          const std::uint32_t word = packPair(code.atoms[s], q, indexBits);
          pairs.push_back(std::uint8_t(word)), pairs.push_back(std::uint8_t(word >> 8));
          pairs.push_back(std::uint8_t(word >> 16));
          ++count;
        }
        counts[std::size_t(inGrid[i])] = std::uint8_t(count);
      }
      progress.advance(inGrid.size());
    });
    progress.end();
    for (const auto& p : out.pairs) out.pairCount += p.size() / 3;
    return out;
  };
  double blockTolerance = tolerance;
  Coded result;
  if (params.targetBitsPerVoxel > 0) {
    // The smallest tolerance whose file fits: every block gets the pairs its error needs, up to
    // S (bisection; the size falls as the tolerance grows).
    const double budget = params.targetBitsPerVoxel * double(volume.voxelCount()) / 8.0;
    const double fixed = double(fixedBytes) + double(atoms) * m * 2;
    auto fits = [&](const Coded& c) { return fixed + 3.0 * double(c.pairCount) <= budget; };
    result = codeAt(0, "sparse coding (rate search)");
    if (!fits(result)) {
      double lo = 0, hi = 0.5;
      Coded loosest = codeAt(hi, "sparse coding (rate search)");
      if (!fits(loosest))
        throw std::invalid_argument(formatLine(
            "--bits-per-voxel %g is below the smallest ksvd file of this volume with %d atoms "
            "(%.3g bits per voxel)",
            params.targetBitsPerVoxel, atoms,
            8.0 * (fixed + 3.0 * double(loosest.pairCount)) / double(volume.voxelCount())));
      result = std::move(loosest);
      for (int it = 0; it < 10; ++it) {
        const double mid = 0.5 * (lo + hi);
        Coded c = codeAt(mid, "sparse coding (rate search)");
        if (fits(c))
          hi = mid, result = std::move(c);
        else
          lo = mid;
      }
      blockTolerance = hi;
    }
  } else {
    result = codeAt(tolerance, "sparse coding");
  }
  for (std::size_t c = 0; c < coded.size(); ++c) bricks[coded[c]].step = result.steps[c];
  const std::vector<std::vector<std::uint8_t>>& brickCounts = result.counts;
  const std::vector<std::vector<std::uint8_t>>& brickPairs = result.pairs;
  stats.codeSeconds = seconds(start);

  // The sections.
  const std::uint64_t pairCount = result.pairCount;
  CompressedVolume out;
  out.info = volumeInfo(volume, CodecId::SparseCoding);
  auto writeParams = [&](double psnr) {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    w.put<std::uint32_t>(std::uint32_t(g.m));
    w.put<std::uint32_t>(std::uint32_t(g.n));
    w.put<std::uint32_t>(std::uint32_t(atoms));
    w.put<std::uint32_t>(std::uint32_t(sparsity));
    w.put<std::uint32_t>(std::uint32_t(indexBits));
    w.put<std::uint32_t>(std::uint32_t(params.iterations));
    w.put<std::uint64_t>(coded.size());
    w.put<std::uint64_t>(pairCount);
    w.put<std::uint64_t>(stats.coreset);
    w.put<double>(blockTolerance);
    w.put<double>(psnr);
    return bytes;
  };
  out.sections.emplace_back(kParams, writeParams(std::numeric_limits<double>::infinity()));
  {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    for (std::int16_t v : stored) w.put<std::int16_t>(v);
    out.sections.emplace_back(kDictionary, std::move(bytes));
  }
  {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    for (const BrickRecord& r : bricks) {
      w.put<float>(r.lo), w.put<float>(r.hi);
      w.put<float>(r.coded == kConstant ? 0.0f : r.step);
      w.put<std::uint32_t>(r.coded);
    }
    out.sections.emplace_back(kBricks, std::move(bytes));
  }
  {
    std::vector<std::byte> counts, pairs;
    counts.reserve(coded.size() * std::size_t(perBrick)), pairs.reserve(pairCount * 3);
    for (std::size_t c = 0; c < coded.size(); ++c) {
      for (std::uint8_t v : brickCounts[c]) counts.push_back(std::byte(v));
      for (std::uint8_t v : brickPairs[c]) pairs.push_back(std::byte(v));
    }
    out.sections.emplace_back(kCounts, std::move(counts));
    out.sections.emplace_back(kPairs, std::move(pairs));
  }
  stats.bricks = nBricks, stats.constantBricks = nBricks - coded.size();
  stats.candidateBlocks = candidates.size(), stats.codedBlocks = candidates.size();
  stats.pairs = pairCount, stats.atoms = atoms, stats.sparsity = sparsity;
  stats.trainSparsity = trainSparsity;
  stats.iterations = params.iterations;
  stats.dictionaryBytes = out.sections[1].second.size();
  stats.brickBytes = out.sections[2].second.size();
  stats.countBytes = out.sections[3].second.size();
  stats.pairBytes = out.sections[4].second.size();
  // The quality of what was stored, measured on the decoder's output.
  progress.begin("measuring PSNR", 1);
  stats.psnr = psnr(volume, decode(out.info, out.view()));
  progress.advance();
  progress.end();
  out.sections[0].second = writeParams(stats.psnr);
  return out;
}

}  // namespace

int blocksPerBrick(int blockSide) {
  switch (blockSide) {
    case 4:
      return 8;
    case 6:
      return 5;
    case 8:
      return 4;
  }
  throw std::invalid_argument("--block must be 4, 6 or 8, not " + std::to_string(blockSide));
}

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* statsOut) {
  (void)blocksPerBrick(params.blockSide);
  if (params.atoms != 0 && (params.atoms < 2 || params.atoms > kMaxAtoms))
    throw std::invalid_argument("--atoms must be in 2..65536");
  if (params.sparsity < 1 || params.sparsity > 255)
    throw std::invalid_argument("--sparsity must be in 1..255");
  if (!(params.tolerance >= 0 && params.tolerance < 1))
    throw std::invalid_argument("--tolerance must be in [0, 1)");
  if (params.iterations < 0 || params.iterations > 10000)
    throw std::invalid_argument("K-SVD iterations must be in 0..10000");
  if (!(params.coreset >= 0) || !std::isfinite(params.coreset))
    throw std::invalid_argument("--coreset must be a count or a fraction in (0, 1]");
  if (volume.voxelCount() == 0) throw std::invalid_argument("ksvd codec: empty volume");
  EncodeStats stats;
  CompressedVolume out = dispatchScalar(volume.type, [&](auto t) {
    return encodeTyped<decltype(t)>(volume, params, progress, stats);
  });
  if (statsOut) *statsOut = stats;
  return out;
}

// ---- reading ------------------------------------------------------------------------------

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  static std::atomic<std::uint64_t> nextCacheId{1};
  cacheId_ = nextCacheId.fetch_add(1);
  const std::string& src = sections.source;
  ByteReader r(sections.get(kParams, "params"), src, "section 'params'");
  m_ = int(r.get<std::uint32_t>());
  n_ = int(r.get<std::uint32_t>());
  k_ = int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 1u << 30));
  s_ = int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 1u << 30));
  indexBits_ = int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 64));
  iterations_ = int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 1u << 30));
  codedBricks_ = r.get<std::uint64_t>();
  pairs_ = r.get<std::uint64_t>();
  coreset_ = r.get<std::uint64_t>();
  tolerance_ = r.get<double>();
  psnr_ = r.get<double>();
  auto fail = [&](const std::string& what) { r.fail(what); };
  if (m_ != 4 && m_ != 6 && m_ != 8) fail("block side " + std::to_string(m_) + " (4, 6 or 8)");
  if (n_ != blocksPerBrick(m_))
    fail("blocks per brick " + std::to_string(n_) + " for block side " + std::to_string(m_));
  const int m = m_ * m_ * m_;
  if (k_ < 2 || k_ > kMaxAtoms) fail("atoms " + std::to_string(k_) + " (2..65536)");
  if (s_ < 1 || s_ > std::min(m, 255)) fail("sparsity " + std::to_string(s_));
  if (indexBits_ != indexBitsFor(k_))
    fail("index bits " + std::to_string(indexBits_) + " for " + std::to_string(k_) + " atoms");
  if (!(tolerance_ >= 0 && tolerance_ < 1)) fail("tolerance out of range");
  if (std::isnan(psnr_)) fail("PSNR is not a number");
  const Grid g(info.dims, m_);
  blocks_ = g.blocks, bricks_ = g.bricks;
  const std::uint64_t nBricks = g.brickCount(), perBrick = std::uint64_t(g.blocksPerBrick());
  if (codedBricks_ > nBricks)
    fail(std::to_string(codedBricks_) + " coded bricks of " + std::to_string(nBricks));

  const auto dictBytes = sections.get(kDictionary, "dictionary");
  if (dictBytes.size() != std::uint64_t(k_) * std::uint64_t(m) * 2)
    ByteReader(dictBytes, src, "section 'dictionary'")
        .fail(std::to_string(dictBytes.size()) + " bytes for " + std::to_string(k_) + " atoms of " +
              std::to_string(m) + " 16-bit values");
  const auto brickBytes = sections.get(kBricks, "bricks");
  ByteReader br(brickBytes, src, "section 'bricks'");
  if (brickBytes.size() != nBricks * 16)
    br.fail(std::to_string(brickBytes.size()) + " bytes for " + std::to_string(nBricks) +
            " bricks of 16 bytes");
  const auto countBytes = sections.get(kCounts, "counts");
  ByteReader cr(countBytes, src, "section 'counts'");
  if (countBytes.size() != codedBricks_ * perBrick)
    cr.fail(std::to_string(countBytes.size()) + " bytes for " + std::to_string(codedBricks_) +
            " coded bricks of " + std::to_string(perBrick) + " blocks");
  const auto pairBytes = sections.get(kPairs, "pairs");
  ByteReader pr(pairBytes, src, "section 'pairs'");
  if (pairs_ > pairBytes.size() / 3 || pairBytes.size() != pairs_ * 3)
    pr.fail(std::to_string(pairBytes.size()) + " bytes for " + std::to_string(pairs_) +
            " pairs of 3 bytes");

  // The render buffer: float atoms, brick records, block table, pairs.
  auto align8 = [](std::uint64_t v) { return (v + 7) / 8 * 8; };
  atomsAt_ = 0;
  bricksAt_ = align8(std::uint64_t(k_) * std::uint64_t(m) * 4);
  blocksAt_ = align8(bricksAt_ + nBricks * sizeof(kernels::KsvdBrick));
  pairsAt_ = align8(blocksAt_ + g.blockCount() * 4);
  render_.assign(pairsAt_ + pairBytes.size() + 8, std::byte{0});
  auto* atoms = reinterpret_cast<float*>(render_.data() + atomsAt_);
  for (std::size_t i = 0; i < std::size_t(k_) * std::size_t(m); ++i) {
    std::int16_t v;
    std::memcpy(&v, dictBytes.data() + 2 * i, 2);
    atoms[i] = float(v) / 32767.0f;
  }
  auto* brickOut = reinterpret_cast<kernels::KsvdBrick*>(render_.data() + bricksAt_);
  auto* blockOut = reinterpret_cast<std::uint32_t*>(render_.data() + blocksAt_);
  const auto* counts = reinterpret_cast<const std::uint8_t*>(countBytes.data());
  const auto* pairs = reinterpret_cast<const std::uint8_t*>(pairBytes.data());
  std::uint64_t codedSeen = 0, pairSeen = 0;
  for (std::uint64_t b = 0; b < nBricks; ++b) {
    kernels::KsvdBrick& out = brickOut[b];
    out.lo = br.get<float>(), out.hi = br.get<float>(), out.step = br.get<float>();
    const std::uint32_t index = br.get<std::uint32_t>();
    auto which = [b] { return "brick " + std::to_string(b); };
    if (!std::isfinite(out.lo) || !std::isfinite(out.hi) || out.lo > out.hi)
      br.fail(which() + ": bad value range");
    if (!std::isfinite(out.step) || out.step < 0) br.fail(which() + ": bad coefficient step");
    if (out.step == 0) {
      if (index != kConstant || out.lo != out.hi)
        br.fail(which() + ": a constant brick must have min == max and no coded index");
      continue;
    }
    if (index != codedSeen)
      br.fail(which() + ": coded index " + std::to_string(index) + ", expected " +
              std::to_string(codedSeen));
    if (codedSeen >= codedBricks_)
      br.fail("more coded bricks than the header's " + std::to_string(codedBricks_));
    out.firstPair = pairSeen;
    const glm::ivec3 bc = g.brickCoords(b);
    std::uint64_t relative = 0;
    for (int j = 0; j < int(perBrick); ++j) {
      const int count = counts[codedSeen * perBrick + std::uint64_t(j)];
      const glm::ivec3 block = g.blockOf(bc, j);
      if (!g.inGrid(block)) {
        if (count != 0) cr.fail(which() + ": a block outside the volume has pairs");
        continue;
      }
      if (count > s_)
        cr.fail(which() + ": block " + std::to_string(j) + " has " + std::to_string(count) +
                " pairs (0.." + std::to_string(s_) + ")");
      if (pairSeen + std::uint64_t(count) > pairs_)
        pr.fail("the blocks need more than the header's " + std::to_string(pairs_) + " pairs");
      for (int p = 0; p < count; ++p) {
        const std::uint8_t* q = pairs + 3 * (pairSeen + std::uint64_t(p));
        const int atom =
            int((std::uint32_t(q[0]) | (std::uint32_t(q[1]) << 8) | (std::uint32_t(q[2]) << 16)) &
                ((1u << indexBits_) - 1u));
        if (atom >= k_)
          pr.fail("pair " + std::to_string(pairSeen + std::uint64_t(p)) + " names atom " +
                  std::to_string(atom) + " of " + std::to_string(k_));
      }
      blockOut[(std::uint64_t(block.z) * std::uint64_t(g.blocks.y) + std::uint64_t(block.y)) *
                   std::uint64_t(g.blocks.x) +
               std::uint64_t(block.x)] = std::uint32_t(relative) | (std::uint32_t(count) << 24);
      relative += std::uint64_t(count), pairSeen += std::uint64_t(count);
    }
    ++codedSeen;
  }
  if (codedSeen != codedBricks_)
    br.fail(std::to_string(codedSeen) + " coded bricks, the header says " +
            std::to_string(codedBricks_));
  if (pairSeen != pairs_)
    pr.fail(std::to_string(pairSeen) + " pairs used, the header says " + std::to_string(pairs_));
  if (!pairBytes.empty())
    std::memcpy(render_.data() + pairsAt_, pairBytes.data(), pairBytes.size());
}

std::uint64_t Layout::bricks() const {
  return std::uint64_t(bricks_.x) * std::uint64_t(bricks_.y) * std::uint64_t(bricks_.z);
}

template <int Side>
kernels::KsvdView<Side> Layout::view(const std::byte* base) const {
  if (Side != m_) throw std::logic_error("ksvd view of the wrong block side");
  kernels::KsvdView<Side> v;
  v.setDims(info_.dims.x, info_.dims.y, info_.dims.z);
  v.cacheId = cacheId_;
  auto& d = v.decoder;
  d.data = reinterpret_cast<const std::uint8_t*>(base ? base : render_.data());
  d.atomsAt = atomsAt_, d.bricksAt = bricksAt_, d.blocksAt = blocksAt_, d.pairsAt = pairsAt_;
  d.blocksX = blocks_.x, d.blocksY = blocks_.y;
  d.bricksX = bricks_.x, d.bricksY = bricks_.y;
  d.blocksPerBrick = n_, d.indexBits = indexBits_;
  return v;
}
template kernels::KsvdView<4> Layout::view<4>(const std::byte*) const;
template kernels::KsvdView<6> Layout::view<6>(const std::byte*) const;
template kernels::KsvdView<8> Layout::view<8>(const std::byte*) const;

RangeGrid Layout::rangeGrid() const {
  switch (m_) {
    case 4:
      return brickRangeGrid(view<4>());
    case 6:
      return brickRangeGrid(view<6>());
    default:
      return brickRangeGrid(view<8>());
  }
}

Volume Layout::decode() const {
  switch (m_) {
    case 4:
      return decodeBricks(view<4>(), info_.type, info_.spacing);
    case 6:
      return decodeBricks(view<6>(), info_.type, info_.spacing);
    default:
      return decodeBricks(view<8>(), info_.type, info_.spacing);
  }
}

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  return Layout(info, sections).decode();
}

}  // namespace voxwall::codec::ksvd
