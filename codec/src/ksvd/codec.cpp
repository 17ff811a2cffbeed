// The ksvd codec's encoder (layout.cpp reads the files back); the byte layout is documented in
// ksvd_codec.hpp.
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
#include <voxwall/core/text.hpp>

#include "format.hpp"
#include "learning.hpp"

namespace voxwall::codec::ksvd {
namespace {

constexpr std::uint64_t kDefaultCoreset = 32768;  // training blocks when --coreset is not given

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// One level of the pyramid: level 0 reads the input, coarser levels their own floats.
template <class T>
struct Source {
  std::span<const T> data;  // level 0
  Volume coarse;            // levels above 0: float32, value range computed
  glm::ivec3 dims;
  float at(int x, int y, int z) const {
    x = std::min(x, dims.x - 1), y = std::min(y, dims.y - 1), z = std::min(z, dims.z - 1);
    const std::size_t i =
        (std::size_t(z) * std::size_t(dims.y) + std::size_t(y)) * std::size_t(dims.x) +
        std::size_t(x);
    return coarse.data.empty() ? float(data[i]) : coarse.as<float>()[i];
  }
  // Block b's voxels (edge-padded), minus `lo`, divided by `scale`.
  void block(glm::ivec3 b, int m, float lo, float scale, float* out) const {
    const float inv = 1.0f / scale;
    for (int z = 0, i = 0; z < m; ++z)
      for (int y = 0; y < m; ++y)
        for (int x = 0; x < m; ++x, ++i)
          out[i] = (at(b.x * m + x, b.y * m + y, b.z * m + z) - lo) * inv;
  }
  // The next level: each voxel the mean of the 2x2x2 voxels below it (clamped at the far faces).
  Source halved(glm::dvec3 spacing, int threads) const {
    Source out;
    out.dims = (dims - 1) / 2 + 1;
    out.coarse = Volume::allocate(out.dims, ScalarType::Float32, spacing);
    const std::span<float> values = out.coarse.template as<float>();
    parallelFor(std::size_t(out.dims.z), threads, [&](std::size_t zs) {
      const int z = int(zs);
      for (int y = 0; y < out.dims.y; ++y)
        for (int x = 0; x < out.dims.x; ++x) {
          double sum = 0;
          for (int j = 0; j < 8; ++j)
            sum += at(2 * x + (j & 1), 2 * y + ((j >> 1) & 1), 2 * z + (j >> 2));
          values[(std::size_t(z) * std::size_t(out.dims.y) + std::size_t(y)) *
                     std::size_t(out.dims.x) +
                 std::size_t(x)] = float(sum / 8.0);
        }
    });
    out.coarse.computeRange();
    return out;
  }
};

// Pyramid levels: `requested`, or (0) until a level fits in one brick.
int levelCount(glm::ivec3 dims, int brickVoxels, int requested) {
  if (requested > 0) return requested;
  int levels = 1;
  while (levels < kernels::kKsvdMaxLevels && std::max({dims.x, dims.y, dims.z}) > brickVoxels)
    dims = (dims - 1) / 2 + 1, ++levels;
  return levels;
}

struct BrickRecord {
  float lo = 0, hi = 0, step = 0;
  std::uint32_t coded = kConstant;
};

template <class T>
CompressedVolume encodeTyped(const Volume& volume, const Params& params, Progress& progress,
                             EncodeStats& stats) {
  const int m = params.blockSide * params.blockSide * params.blockSide;
  const int perBrick = Grid(volume.dims, params.blockSide).blocksPerBrick();
  // The value range: the scale blocks are coded in, and the tolerance's unit.
  float vmin = std::numeric_limits<float>::infinity(), vmax = -vmin;
  for (T v : volume.as<T>()) {
    if (!std::isfinite(float(v)))
      throw std::invalid_argument("ksvd codec: the volume holds NaN or infinite values");
    vmin = std::min(vmin, float(v)), vmax = std::max(vmax, float(v));
  }
  const float scale = vmax > vmin ? vmax - vmin : 1.0f;
  const double tolerance = params.tolerance;

  // The pyramid, and the bricking of each level; bricks are numbered across levels.
  std::vector<Source<T>> src;
  std::vector<Grid> grids;
  std::vector<std::uint64_t> firstBrick;
  const int levels = levelCount(
      volume.dims, Grid(volume.dims, params.blockSide).n * params.blockSide, params.levels);
  std::uint64_t nBricks = 0;
  for (int l = 0; l < levels; ++l) {
    if (l == 0) {
      Source<T> base;
      base.data = volume.as<T>(), base.dims = volume.dims;
      src.push_back(std::move(base));
    } else {
      progress.begin("pyramid level " + std::to_string(l), 1);
      src.push_back(src.back().halved(volume.spacing * double(1 << l), params.threads));
      progress.advance();
      progress.end();
    }
    grids.emplace_back(src.back().dims, params.blockSide);
    firstBrick.push_back(nBricks);
    nBricks += grids.back().brickCount();
  }
  auto levelOf = [&](std::uint64_t b) {
    int l = levels - 1;
    while (firstBrick[std::size_t(l)] > b) --l;
    return l;
  };

  // Bricks: value ranges; constant bricks keep their mean.
  std::vector<BrickRecord> bricks(nBricks);
  progress.begin("bricking", nBricks);
  parallelFor(std::size_t(nBricks), params.threads, [&](std::size_t b) {
    const int l = levelOf(b);
    const Grid& g = grids[std::size_t(l)];
    const Source<T>& s = src[std::size_t(l)];
    const glm::ivec3 bc = g.brickCoords(b - firstBrick[std::size_t(l)]);
    const glm::ivec3 lo = bc * g.n * g.m, hi = glm::min(lo + g.n * g.m, g.dims);
    float l0 = std::numeric_limits<float>::infinity(), h = -l0;
    double sum = 0;
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) {
          const float v = s.at(x, y, z);
          l0 = std::min(l0, v), h = std::max(h, v), sum += v;
        }
    BrickRecord& r = bricks[b];
    if (double(h) - double(l0) <= tolerance * double(scale)) {
      const double count = double(hi.x - lo.x) * double(hi.y - lo.y) * double(hi.z - lo.z);
      r.lo = r.hi = h == l0 ? l0 : float(sum / count);
    } else {
      r.lo = l0, r.hi = h;
    }
    progress.advance();
  });
  progress.end();
  std::vector<std::uint64_t> coded;  // brick indices of the coded bricks, in level order
  for (std::uint64_t b = 0; b < nBricks; ++b)
    if (bricks[b].lo != bricks[b].hi)
      bricks[b].coded = std::uint32_t(coded.size()), coded.push_back(b);
  if (coded.size() >= kConstant) throw std::invalid_argument("ksvd codec: too many bricks");
  // A coded brick's level, grid, source and brick coordinates.
  struct Where {
    const Grid* g;
    const Source<T>* s;
    glm::ivec3 brick;
  };
  auto where = [&](std::uint64_t b) {
    const int l = levelOf(b);
    const Grid& g = grids[std::size_t(l)];
    return Where{&g, &src[std::size_t(l)], g.brickCoords(b - firstBrick[std::size_t(l)])};
  };
  // The blocks to code: every in-grid block of every coded brick of every level, in brick
  // order. The dictionary is learned on level 0's (the first `trainable`): the full resolution
  // is what the file is judged by, and coarse blocks, busier than fine ones, would take a large
  // share of the coreset (on the MRI at 0.5 bits per voxel, 1.4 dB of level 0's PSNR).
  std::vector<std::uint64_t> candidates;  // coded-brick index * perBrick + j
  std::uint64_t trainable = 0;
  for (std::size_t c = 0; c < coded.size(); ++c) {
    const Where w = where(coded[c]);
    for (int j = 0; j < perBrick; ++j)
      if (w.g->inGrid(w.g->blockOf(w.brick, j))) {
        candidates.push_back(std::uint64_t(c) * perBrick + j);
        if (coded[c] < grids[0].brickCount()) ++trainable;
      }
  }
  auto candidateBlock = [&](std::uint64_t i, float* out) {
    const std::uint64_t c = candidates[std::size_t(i)] / std::uint64_t(perBrick);
    const int j = int(candidates[std::size_t(i)] % std::uint64_t(perBrick));
    const std::uint64_t b = coded[std::size_t(c)];
    const Where w = where(b);
    w.s->block(w.g->blockOf(w.brick, j), w.g->m, bricks[b].lo, scale, out);
  };

  // Dictionary size, sparsity and training-set size.
  const std::uint64_t fixedBytes = nBricks * 16 +
                                   std::uint64_t(coded.size()) * std::uint64_t(perBrick) + 128 + 4 +
                                   8 * std::uint64_t(levels);
  int atoms = params.atoms;
  if (atoms == 0) {  // the default: 1024, at most one atom per 16 coded blocks, at least 16
    atoms = int(std::clamp<std::uint64_t>(trainable / 16, 16, 1024));
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
    coresetSize = std::uint64_t(std::ceil(params.coreset * double(trainable)));
  coresetSize = std::min<std::uint64_t>(coresetSize, trainable);

  // Learning.
  Dictionary dict;
  dict.m = m;
  auto start = std::chrono::steady_clock::now();
  if (trainable > 0) {
    const TrainingSet set =
        buildCoreset(trainable, m, candidateBlock, coresetSize, params.seed, progress);
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
      const Where w = where(b);
      std::vector<float> y(std::size_t(perBrick) * std::size_t(m));
      std::vector<int> inGrid;
      for (int j = 0; j < perBrick; ++j)
        if (w.g->inGrid(w.g->blockOf(w.brick, j))) {
          w.s->block(w.g->blockOf(w.brick, j), w.g->m, bricks[b].lo, scale,
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
  out.info = volumeInfo(volume, KsvdCodecEntry::kId);
  auto writeParams = [&](double psnr) {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    w.put<std::uint32_t>(std::uint32_t(grids[0].m));
    w.put<std::uint32_t>(std::uint32_t(grids[0].n));
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
  auto writeLevels = [&](const std::vector<double>& psnrs) {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    w.put<std::uint32_t>(std::uint32_t(levels));
    for (double v : psnrs) w.put<double>(v);
    return bytes;
  };
  std::vector<double> levelPsnr(std::size_t(levels), std::numeric_limits<double>::infinity());
  out.sections.emplace_back(kLevels, writeLevels(levelPsnr));
  stats.bricks = nBricks, stats.constantBricks = nBricks - coded.size();
  stats.codedBlocks = candidates.size();
  stats.pairs = pairCount, stats.atoms = atoms, stats.sparsity = sparsity;
  stats.trainSparsity = trainSparsity;
  stats.iterations = params.iterations;
  stats.levels = levels;
  stats.levelPairs = 0;
  for (std::size_t c = 0; c < coded.size(); ++c)
    if (coded[c] >= grids[0].brickCount()) stats.levelPairs += brickPairs[c].size() / 3;
  stats.dictionaryBytes = out.sections[1].second.size();
  stats.brickBytes = out.sections[2].second.size() + out.sections[5].second.size();
  stats.countBytes = out.sections[3].second.size();
  stats.pairBytes = out.sections[4].second.size();
  // The quality of what was stored, measured on the decoder's output, level by level.
  progress.begin("measuring PSNR", std::uint64_t(levels));
  {
    const Layout layout(out.info, out.view());
    stats.psnr = levelPsnr[0] = psnr(volume, layout.decode());
    progress.advance();
    for (int l = 1; l < levels; ++l) {
      levelPsnr[std::size_t(l)] = psnr(src[std::size_t(l)].coarse, layout.decodeLevel(l));
      progress.advance();
    }
  }
  progress.end();
  stats.levelPsnr = levelPsnr;
  out.sections[0].second = writeParams(stats.psnr);
  out.sections[5].second = writeLevels(levelPsnr);
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
  if (params.levels < 0 || params.levels > kernels::kKsvdMaxLevels)
    throw std::invalid_argument("--levels must be in 1.." +
                                std::to_string(kernels::kKsvdMaxLevels));
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

}  // namespace voxwall::codec::ksvd
