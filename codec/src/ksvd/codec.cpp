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
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>
#include <voxwall/core/text.hpp>

#include "block_codes.hpp"
#include "format.hpp"
#include "learning.hpp"
#include "pyramid.hpp"

namespace voxwall::codec::ksvd {
namespace {

constexpr std::uint64_t kDefaultCoreset = 32768;  // training blocks when --coreset is not given

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

struct BrickRecord {
  float lo = 0, hi = 0, step = 0;
  std::uint32_t coded = kConstant;
};

// The encoder of a volume of scalar type T, stage by stage (run): the pyramid and its bricks, the
// blocks to code, the dictionary's size and its learning, the coding (at a size target, the
// tolerance whose file fits), the sections and the PSNR of every level.
//
// The input is read a row of level-0 bricks at a time where it streams (a window of N x M
// slices, M^3-voxel blocks, N^3 blocks a brick), and so is level 1, made from the input two
// slices at a time as it is read: the stages that read them (bricking, the coreset's passes,
// every coding pass, the PSNR) walk their bricks row by row in brick order. The levels above
// (float, 1/56 of the voxels together) are made from level 1's windows and held whole. Held in
// memory, the input is read in place and every coarser level is held.
template <class T>
class Encoder {
 public:
  Encoder(const VolumeSource& source, const Params& params, Progress& progress, EncodeStats& stats)
      : source_(source),
        header_(source.headerVolume()),
        params_(params),
        progress_(progress),
        stats_(stats),
        m_(params.blockSide * params.blockSide * params.blockSide),
        perBrick_(Grid(source.dims, params.blockSide).blocksPerBrick()) {
    // The value range: the scale blocks are coded in, and the tolerance's unit (the source's,
    // scanned for a volume in memory, found by the first pass over a file).
    if (!source.finite)
      throw std::invalid_argument("ksvd codec: the volume holds NaN or infinite values");
    const auto [lo, hi] = source.dataRange();
    const float vmin = float(lo), vmax = float(hi);
    scale_ = vmax > vmin ? vmax - vmin : 1.0f;
  }

  std::vector<std::int16_t> learnOnly() {
    pyramid();
    brickRanges();
    findCandidates();
    chooseSizes();
    learn();
    return stored_;
  }

  CompressedVolume run() {
    pyramid();
    brickRanges();
    findCandidates();
    chooseSizes();
    auto start = std::chrono::steady_clock::now();
    learn();
    stats_.trainSeconds = seconds(start);
    start = std::chrono::steady_clock::now();
    code();
    stats_.codeSeconds = seconds(start);
    CompressedVolume out = sections();
    measure(out);
    return out;
  }

 private:
  // A coded brick's level, grid, source and brick coordinates.
  struct Where {
    const Grid* g;
    const Source<T>* s;
    glm::ivec3 brick;
  };
  int levelOf(std::uint64_t b) const {
    int l = levels_ - 1;
    while (firstBrick_[std::size_t(l)] > b) --l;
    return l;
  }
  Where where(std::uint64_t b) const {
    const int l = levelOf(b);
    const Grid& g = grids_[std::size_t(l)];
    return Where{&g, &src_[std::size_t(l)], g.brickCoords(b - firstBrick_[std::size_t(l)])};
  }
  double budgetBytes() const {
    return params_.targetBitsPerVoxel * double(source_.voxelCount()) / 8.0;
  }

  // Whether level l is read a window at a time: levels 0 and 1 of an input that streams.
  bool streamed(int l) const { return !source_.inMemory() && l <= 1; }
  // Level l's slices z0 .. z1 - 1 (within the level) readable by src_[l].at: read into its
  // window unless it holds them already (or holds the whole level).
  void window(int l, int z0, int z1) {
    Source<T>& s = src_[std::size_t(l)];
    if (z0 >= s.z0 && z1 <= s.z0 + s.slices) return;
    if (l == 0) {
      window_.resize(std::size_t(z1 - z0) * source_.sliceVoxels());
      source_.readSlices(z0, z1 - z0, std::as_writable_bytes(std::span(window_)));
      s.data = window_;
    } else {
      window1_.resize(std::size_t(z1 - z0) * half_->sliceVoxels());
      half_->readSlices(z0, z1 - z0, std::as_writable_bytes(std::span(window1_)));
      s.floats = window1_;
    }
    s.z0 = z0, s.slices = z1 - z0;
  }
  // Brick b's level and its row of bricks (its z) there.
  std::pair<int, int> rowOf(std::uint64_t b) const {
    const int l = levelOf(b);
    const Grid& g = grids_[std::size_t(l)];
    return {l, g.brickCoords(b - firstBrick_[std::size_t(l)]).z};
  }
  // The slices brick row `bz` of level l reads.
  void windowOfRow(int l, int bz) {
    const Grid& g = grids_[std::size_t(l)];
    window(l, bz * g.n * g.m, std::min((bz + 1) * g.n * g.m, g.dims.z));
  }
  // f(first, end) for each run of `items` (indices of increasing bricks, brickOf(i) the brick)
  // in one row of bricks of a streamed level, with that row's window, then once for the rest
  // (the levels held whole); a single run of all items when the input is in memory.
  template <class BrickOf, class F>
  void byStreamedRows(std::size_t items, BrickOf&& brickOf, F&& f) {
    std::size_t first = 0;
    while (first < items) {
      const auto row = rowOf(brickOf(first));
      if (!streamed(row.first)) break;
      std::size_t end = first + 1;
      while (end < items && rowOf(brickOf(end)) == row) ++end;
      windowOfRow(row.first, row.second);
      f(first, end);
      first = end;
    }
    if (first < items) f(first, items);
  }

  // The pyramid, and the bricking of each level; bricks are numbered across levels. Level 1 of
  // an input that streams is made from it as it is read (HalvedSource), after a pass that finds
  // its value range; the levels above it are made from its windows and held.
  void pyramid() {
    levels_ = levelCount(source_.dims, Grid(source_.dims, params_.blockSide).n * params_.blockSide,
                         params_.levels);
    for (int l = 0; l < levels_; ++l) {
      progress_.begin("pyramid level " + std::to_string(l), 1);
      if (l == 0) {
        Source<T> base;
        base.base = true, base.dims = source_.dims;
        if (const Volume* whole = source_.inMemory())
          base.data = whole->as<T>(), base.slices = source_.dims.z;
        src_.push_back(std::move(base));
      } else if (streamed(l)) {
        half_ = std::make_unique<HalvedSource<T>>(source_, source_.spacing * 2.0, params_.threads);
        Source<T> one;
        one.dims = half_->dims;
        src_.push_back(std::move(one));
        levelOneRange();
      } else {
        src_.push_back(src_.back().halved(source_.spacing * double(1 << l), params_.threads,
                                          [&](int z0, int z1) {
                                            if (streamed(l - 1)) window(l - 1, z0, z1);
                                          }));
      }
      progress_.advance();
      progress_.end();
      grids_.emplace_back(src_.back().dims, params_.blockSide);
      firstBrick_.push_back(nBricks_);
      nBricks_ += grids_.back().brickCount();
    }
  }
  // The windows' memory given back (the PSNR reads the sources a few rows of bricks at a time).
  void dropWindows() {
    for (int l = 0; l < std::min(levels_, 2); ++l)
      if (streamed(l)) src_[std::size_t(l)].slices = 0;
    window_ = {}, window1_ = {};
  }
  // Level 1's value range (what its PSNR is measured against), as Volume::computeRange finds it.
  void levelOneRange() {
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (int z = 0; z < half_->dims.z; z += 32) {
      window(1, z, std::min(z + 32, half_->dims.z));
      for (const float v : window1_) lo = std::min(lo, v), hi = std::max(hi, v);
    }
    half_->valueMin = double(lo), half_->valueMax = double(hi);
  }

  // Bricks: value ranges; constant bricks keep their mean. The others are coded, in level order.
  void brickRanges() {
    bricks_.assign(nBricks_, BrickRecord{});
    progress_.begin("bricking", nBricks_);
    byStreamedRows(
        std::size_t(nBricks_), [](std::size_t b) { return std::uint64_t(b); },
        [&](std::size_t first, std::size_t end) {
          parallelFor(end - first, params_.threads, [&](std::size_t i) { brickRange(first + i); });
        });
    progress_.end();
    for (std::uint64_t b = 0; b < nBricks_; ++b)
      if (bricks_[b].lo != bricks_[b].hi)
        bricks_[b].coded = std::uint32_t(coded_.size()), coded_.push_back(b);
    if (coded_.size() >= kConstant) throw std::invalid_argument("ksvd codec: too many bricks");
  }
  void brickRange(std::size_t b) {
    const Where w = where(b);
    const Grid& g = *w.g;
    const glm::ivec3 lo = w.brick * g.n * g.m, hi = glm::min(lo + g.n * g.m, g.dims);
    float l0 = std::numeric_limits<float>::infinity(), h = -l0;
    double sum = 0;
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) {
          const float v = w.s->at(x, y, z);
          l0 = std::min(l0, v), h = std::max(h, v), sum += v;
        }
    BrickRecord& r = bricks_[b];
    if (double(h) - double(l0) <= params_.tolerance * double(scale_)) {
      const double count = double(hi.x - lo.x) * double(hi.y - lo.y) * double(hi.z - lo.z);
      r.lo = r.hi = h == l0 ? l0 : float(sum / count);
    } else {
      r.lo = l0, r.hi = h;
    }
    progress_.advance();
  }

  // The blocks to code: every in-grid block of every coded brick of every level, in brick
  // order. The dictionary is learned on level 0's (the first `trainable`): the full resolution
  // is what the file is judged by, and coarse blocks, busier than fine ones, would take a large
  // share of the coreset (on the MRI at 0.5 bits per voxel, 1.4 dB of level 0's PSNR).
  void findCandidates() {
    for (std::size_t c = 0; c < coded_.size(); ++c) {
      const Where w = where(coded_[c]);
      for (int j = 0; j < perBrick_; ++j)
        if (w.g->inGrid(w.g->blockOf(w.brick, j))) {
          candidates_.push_back(std::uint64_t(c) * perBrick_ + j);
          if (coded_[c] < grids_[0].brickCount()) ++trainable_;
        }
    }
  }
  // Candidate i's block; the coreset's passes ask for level 0's in order, so the window moves
  // a row of bricks at a time.
  void candidateBlock(std::uint64_t i, float* out) {
    const std::uint64_t c = candidates_[std::size_t(i)] / std::uint64_t(perBrick_);
    const int j = int(candidates_[std::size_t(i)] % std::uint64_t(perBrick_));
    const std::uint64_t b = coded_[std::size_t(c)];
    if (streamed(0) && b < grids_[0].brickCount()) windowOfRow(0, rowOf(b).second);
    const Where w = where(b);
    w.s->block(w.g->blockOf(w.brick, j), w.g->m, bricks_[b].lo, scale_, out);
  }

  // Dictionary size, sparsity and training-set size.
  void chooseSizes() {
    fixedBytes_ = nBricks_ * 16 + 128 + 8 + 8 * std::uint64_t(levels_);
    atomBits_ = params_.atomBits > 0 ? params_.atomBits : atomBitsFor(params_.targetBitsPerVoxel);
    atoms_ = params_.atoms;
    if (atoms_ == 0) {  // the default: 1024, at most one atom per 16 coded blocks, at least 16
      atoms_ = int(std::clamp<std::uint64_t>(trainable_ / 16, 16, 1024));
      // and with a size target as many as fit in a quarter of the file at 16 bits a value (the
      // count measured best at 0.25-1 bits per voxel whatever the atoms' width)
      if (params_.targetBitsPerVoxel > 0)
        while (atoms_ > 16 &&
               double(dictionaryBytes(atoms_, m_, kWideAtomBits)) > budgetBytes() / 4)
          atoms_ /= 2;
    }
    const double tables =
        double(fixedBytes_) + double(dictionaryBytes(atoms_, m_, atomBits_)) +
        double(blockTableBytes(codedBlocks(), meanBits(coefficientBits(indexBitsFor(atoms_)))));
    if (params_.targetBitsPerVoxel > 0 && tables > budgetBytes())
      throw tooSmall(tables, ": the dictionary and the brick and block tables alone take");
    sparsity_ = std::min(params_.sparsity, m_);
    // Training codes blocks with the sparsity the file will have on average: S, or with a size
    // target the pairs per block the budget leaves after the dictionary and the tables.
    trainSparsity_ = sparsity_;
    if (params_.targetBitsPerVoxel > 0 && !candidates_.empty()) {
      // The DC atom's, which every block has, and the learned-atom pairs the rest buys (a pair
      // and its bit of unary count).
      const double perBlock =
          1 + (budgetBytes() - tables) /
                  ((pairBytes(indexBitsFor(atoms_)) + 0.125) * double(candidates_.size()));
      // At least 2: training with the DC atom alone leaves the learned atoms unused (at 0.35 bits
      // per voxel on the MRI, blocks of 4^3 lost 2.6 dB).
      trainSparsity_ =
          int(std::clamp(std::lround(perBlock), std::min(2l, long(sparsity_)), long(sparsity_)));
    }
    sparsity_ = std::max(1, std::min(sparsity_, 255));
    coresetSize_ = kDefaultCoreset;
    if (params_.coreset > 1)
      coresetSize_ = std::uint64_t(params_.coreset);
    else if (params_.coreset > 0)
      coresetSize_ = std::uint64_t(std::ceil(params_.coreset * double(trainable_)));
    coresetSize_ = std::min<std::uint64_t>(coresetSize_, trainable_);
  }

  // Learning, then the dictionary the file stores (16 bits, then narrowed to the atoms' width):
  // blocks are coded against exactly that.
  void learn() {
    dict_.m = m_;
    if (params_.dictionary) {  // given (a series' shared one): only its count is checked here
      const auto& given = *params_.dictionary;
      if (given.size() % std::size_t(m_) != 0 || given.size() / std::size_t(m_) < 2)
        throw std::invalid_argument("ksvd codec: a given dictionary of " +
                                    std::to_string(given.size()) + " values is not atoms of " +
                                    std::to_string(m_));
      atoms_ = int(given.size() / std::size_t(m_));
      dict_.atoms = atoms_;
      dict_.values.resize(given.size());
      stored_ = given;
    } else if (trainable_ > 0) {
      const TrainingSet set = buildCoreset(
          trainable_, m_, [&](std::uint64_t i, float* out) { candidateBlock(i, out); },
          coresetSize_, params_.seed, progress_);
      atoms_ = std::max(2, std::min<int>(atoms_, int(std::max<std::size_t>(set.count(), 2))));
      TrainParams tp;
      tp.atoms = atoms_, tp.sparsity = trainSparsity_, tp.iterations = params_.iterations;
      tp.threads = params_.threads, tp.seed = params_.seed;
      dict_ = trainDictionary(set, tp, progress_, &stats_.trainingRmse);
      stats_.coreset = set.count();
    } else {  // nothing to code: the DC atom and one more, so the file stays well-formed
      atoms_ = 2;
      dict_.atoms = 2;
      dict_.values.assign(std::size_t(2 * m_), 0.0f);
      for (int i = 0; i < m_; ++i)
        dict_.values[std::size_t(i)] = float(1 / std::sqrt(double(m_))),
        dict_.values[std::size_t(m_ + i)] = float((i & 1 ? 1 : -1) / std::sqrt(double(m_)));
    }
    if (!params_.dictionary) {
      stored_.resize(dict_.values.size());
      for (std::size_t i = 0; i < stored_.size(); ++i)
        stored_[i] = std::int16_t(std::lround(std::clamp(dict_.values[i], -1.0f, 1.0f) * 32767.0f));
    }
    for (std::size_t i = 0; i < stored_.size(); ++i) dict_.values[i] = float(stored_[i]) / 32767.0f;
    dictSection_ = dictionarySection(dict_.values, m_, atomBits_);
    dict_.values = dictionaryValues(dictSection_, std::uint64_t(atoms_), m_, atomBits_);
    widths_.indexBits = indexBitsFor(atoms_);
    widths_.coefBits = coefficientBits(widths_.indexBits);
    widths_.meanBits = meanBits(widths_.coefBits);
  }

  // The refusal of a size target below the smallest file of these settings (`bytes`).
  SizeTargetTooSmall tooSmall(double bytes, const char* what) const {
    return SizeTargetTooSmall(formatLine(
        "--bits-per-voxel %g is below the smallest ksvd file of this volume with %d atoms and "
        "blocks of %d^3%s %.3g bits per voxel",
        params_.targetBitsPerVoxel, atoms_, params_.blockSide, what,
        8.0 * bytes / double(source_.voxelCount())));
  }

  // The coefficient's width with `indexBits` of atom index, and a pair's bytes in the stream.
  int coefficientBits(int indexBits) const {
    const int room = kMaxPairBits - indexBits;
    if (params_.coefficientBits == 0)
      return params_.targetBitsPerVoxel > 0
                 ? coefficientBitsFor(params_.targetBitsPerVoxel, indexBits)
                 : room;
    if (params_.coefficientBits > room)
      throw std::invalid_argument(formatLine(
          "ksvd codec: --coefficient-bits %d leaves no room for the atom index: a pair is at "
          "most %d bits and %d atoms need %d, so at most %d",
          params_.coefficientBits, kMaxPairBits, atoms_, indexBits, room));
    return params_.coefficientBits;
  }
  double pairBytes(int indexBits) const {
    return double(indexBits + coefficientBits(indexBits)) / 8.0;
  }
  // A block mean's width: --mean-bits, or one less than a coefficient's (a mean is never
  // negative, and its step is the brick's range over 2^bits - 1, not its largest coefficient).
  int meanBits(int coefBits) const {
    return params_.meanBits > 0 ? params_.meanBits : std::max(2, coefBits - 1);
  }
  // The blocks of the coded bricks (past the volume's edge too: each has a mean and a count).
  std::uint64_t codedBlocks() const {
    return std::uint64_t(coded_.size()) * std::uint64_t(perBrick_);
  }

  // Coding: every block of every coded brick, brick by brick, at a per-block tolerance t: a
  // block's code stops once its RMS error is at most t (x the value range), or, `byGain`, once
  // the next pair would take less than t^2 M^3 off its squared error (the same price for a pair
  // everywhere: the least squared error for the pairs, which a size target searches for).
  CodedBricks codeAt(const Coder& coder, double blockTolerance, const char* stage,
                     bool byGain = false) {
    const double threshold2 = blockTolerance * blockTolerance * double(m_);
    CodedBricks out(coded_.size());
    progress_.begin(stage, candidates_.size());
    byStreamedRows(
        coded_.size(), [&](std::size_t c) { return coded_[c]; },
        [&](std::size_t first, std::size_t end) {
          parallelFor(end - first, params_.threads,
                      [&](std::size_t i) { codeBrick(coder, threshold2, byGain, first + i, out); });
        });
    progress_.end();
    for (const auto& p : out.pairs) out.pairCount += p.size();
    return out;
  }

  void codeBrick(const Coder& coder, double threshold2, bool byGain, std::size_t c,
                 CodedBricks& out) {
    const std::uint64_t b = coded_[c];
    const Where w = where(b);
    std::vector<float> y(std::size_t(perBrick_) * std::size_t(m_));
    std::vector<int> inGrid;
    for (int j = 0; j < perBrick_; ++j)
      if (w.g->inGrid(w.g->blockOf(w.brick, j))) {
        w.s->block(w.g->blockOf(w.brick, j), w.g->m, bricks_[b].lo, scale_,
                   y.data() + inGrid.size() * std::size_t(m_));
        inGrid.push_back(j);
      }
    std::vector<SparseCode> codes;
    codeAll(coder, y.data(), inGrid.size(), sparsity_, byGain ? 0.0 : threshold2, 1, codes, {},
            byGain ? threshold2 : 0.0);
    quantizeBrick(codes, y.data(), inGrid, m_, perBrick_, scale_,
                  double(bricks_[b].hi) - double(bricks_[b].lo), widths_, c, out);
    progress_.advance(inGrid.size());
  }

  void code() {
    const Coder coder(dict_);
    blockTolerance_ = params_.tolerance;
    if (params_.targetBitsPerVoxel > 0)
      codeForSize(coder);
    else
      result_ = codeAt(coder, params_.tolerance, "sparse coding");
    for (std::size_t c = 0; c < coded_.size(); ++c) bricks_[coded_[c]].step = result_.steps[c];
  }

  // The smallest tolerance whose file fits: every block gets the pairs its error needs, up to
  // S (bisection; the size falls as the tolerance grows).
  void codeForSize(const Coder& coder) {
    const double fixed = double(fixedBytes_) + double(dictionaryBytes(atoms_, m_, atomBits_));
    auto bytes = [&](const CodedBricks& c) {
      return fixed + double(codeBytes(c, codedBlocks(), widths_));
    };
    auto fits = [&](const CodedBricks& c) { return bytes(c) <= budgetBytes(); };
    result_ = codeAt(coder, 0, "sparse coding (rate search)", true);
    if (fits(result_)) return;
    double lo = 0, hi = 0.5;
    CodedBricks loosest = codeAt(coder, hi, "sparse coding (rate search)", true);
    if (!fits(loosest)) throw tooSmall(bytes(loosest), ": its smallest file takes");
    result_ = std::move(loosest);
    for (int it = 0; it < 10; ++it) {
      const double mid = 0.5 * (lo + hi);
      CodedBricks c = codeAt(coder, mid, "sparse coding (rate search)", true);
      if (fits(c))
        hi = mid, result_ = std::move(c);
      else
        lo = mid;
    }
    blockTolerance_ = hi;
  }

  // The sections.
  std::vector<std::byte> paramsSection(double psnr) const {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    w.put<std::uint32_t>(std::uint32_t(grids_[0].m));
    w.put<std::uint32_t>(std::uint32_t(grids_[0].n));
    w.put<std::uint32_t>(std::uint32_t(atoms_));
    w.put<std::uint32_t>(std::uint32_t(sparsity_));
    w.put<std::uint32_t>(std::uint32_t(widths_.indexBits));
    w.put<std::uint32_t>(std::uint32_t(params_.iterations));
    w.put<std::uint64_t>(coded_.size());
    w.put<std::uint64_t>(result_.pairCount);
    w.put<std::uint64_t>(stats_.coreset);
    w.put<double>(blockTolerance_);
    w.put<double>(psnr);
    w.put<std::uint32_t>(std::uint32_t(widths_.coefBits));
    w.put<std::uint32_t>(std::uint32_t(kLayout));
    w.put<std::uint32_t>(std::uint32_t(widths_.meanBits));
    w.put<std::uint32_t>(std::uint32_t(atomBits_));
    return bytes;
  }
  std::vector<std::byte> levelsSection(const std::vector<double>& psnrs) const {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    w.put<std::uint32_t>(std::uint32_t(levels_));
    for (double v : psnrs) w.put<double>(v);
    return bytes;
  }

  CompressedVolume sections() {
    CompressedVolume out;
    out.info = volumeInfo(header_, KsvdCodecEntry::kId);
    out.sections.emplace_back(kParams, paramsSection(std::numeric_limits<double>::infinity()));
    {
      std::vector<std::byte> bytes;
      ByteWriter w(bytes);
      out.sections.emplace_back(kDictionary, dictSection_);
    }
    {
      std::vector<std::byte> bytes;
      ByteWriter w(bytes);
      for (const BrickRecord& r : bricks_) {
        w.put<float>(r.lo), w.put<float>(r.hi);
        w.put<float>(r.coded == kConstant ? 0.0f : r.step);
        w.put<std::uint32_t>(r.coded);
      }
      out.sections.emplace_back(kBricks, std::move(bytes));
    }
    {
      CodeSections codes = codeSections(result_, perBrick_, widths_);
      out.sections.emplace_back(kCounts, std::move(codes.counts));
      out.sections.emplace_back(kPairs, std::move(codes.pairs));
      out.sections.emplace_back(
          kLevels, levelsSection(std::vector<double>(std::size_t(levels_),
                                                     std::numeric_limits<double>::infinity())));
      out.sections.emplace_back(kDc, std::move(codes.dc));
    }
    stats_.bricks = nBricks_, stats_.constantBricks = nBricks_ - coded_.size();
    stats_.codedBlocks = candidates_.size();
    stats_.pairs = result_.pairCount, stats_.atoms = atoms_, stats_.sparsity = sparsity_;
    stats_.atomBits = atomBits_;
    stats_.trainSparsity = trainSparsity_;
    stats_.indexBits = widths_.indexBits, stats_.coefficientBits = widths_.coefBits;
    stats_.iterations = params_.iterations;
    stats_.levels = levels_;
    stats_.levelPairs = 0;
    for (std::size_t c = 0; c < coded_.size(); ++c)
      if (coded_[c] >= grids_[0].brickCount()) stats_.levelPairs += result_.pairs[c].size();
    stats_.dictionaryBytes = out.sections[1].second.size();
    stats_.brickBytes = out.sections[2].second.size() + out.sections[5].second.size();
    stats_.countBytes = out.sections[3].second.size() + out.sections[6].second.size();
    stats_.pairBytes = out.sections[4].second.size();
    return out;
  }

  // The quality of what was stored, measured on the decoder's output, level by level.
  void measure(CompressedVolume& out) {
    std::vector<double> levelPsnr(std::size_t(levels_), std::numeric_limits<double>::infinity());
    progress_.begin("measuring PSNR", std::uint64_t(levels_));
    {
      const Layout layout(out.info, out.view());
      // A few rows of bricks at a time (brickPsnr: the same sum as psnr() of the whole decode,
      // which held a second copy of the level while it was measured).
      dropWindows();
      stats_.psnr = levelPsnr[0] =
          layout.withView([&](const auto& v) { return brickPsnr(source_, v.level[0]); });
      progress_.advance();
      for (int l = 1; l < levels_; ++l) {
        const std::unique_ptr<VolumeSource> reference =
            streamed(l) ? nullptr : memorySource(src_[std::size_t(l)].coarse);
        const VolumeSource& level = streamed(l) ? *half_ : *reference;
        levelPsnr[std::size_t(l)] =
            layout.withView([&](const auto& v) { return brickPsnr(level, v.level[l]); });
        progress_.advance();
      }
    }
    progress_.end();
    stats_.levelPsnr = levelPsnr;
    out.sections[0].second = paramsSection(stats_.psnr);
    out.sections[5].second = levelsSection(levelPsnr);
  }

  const VolumeSource& source_;
  const Volume header_;                 // the input's dims, type, spacing, orientation and range
  std::vector<T> window_;               // level 0's slices src_[0] reads, when the input streams
  std::unique_ptr<VolumeSource> half_;  // level 1, when the input streams
  std::vector<float> window1_;          // its slices src_[1] reads
  const Params& params_;
  Progress& progress_;
  EncodeStats& stats_;
  const int m_, perBrick_;
  float scale_ = 1;
  std::vector<Source<T>> src_;
  std::vector<Grid> grids_;
  std::vector<std::uint64_t> firstBrick_;
  int levels_ = 1;
  std::uint64_t nBricks_ = 0;
  std::vector<BrickRecord> bricks_;
  std::vector<std::uint64_t> coded_;       // brick indices of the coded bricks, in level order
  std::vector<std::uint64_t> candidates_;  // coded-brick index * perBrick + j
  std::uint64_t trainable_ = 0;
  std::uint64_t fixedBytes_ = 0;
  int atoms_ = 0, sparsity_ = 1, trainSparsity_ = 1, atomBits_ = kWideAtomBits;
  CodeWidths widths_;  // a pair's fields and a block's mean
  std::uint64_t coresetSize_ = 0;
  Dictionary dict_;
  std::vector<std::int16_t> stored_;    // the atoms at 16 bits (what learnDictionary returns)
  std::vector<std::byte> dictSection_;  // section 2: the atoms at atomBits_
  CodedBricks result_;
  double blockTolerance_ = 0;
};

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

namespace {

void checkParams(const Params& params) {
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
  if (params.coefficientBits != 0 &&
      (params.coefficientBits < kMinCoefficientBits || params.coefficientBits > kMaxPairBits - 1))
    throw std::invalid_argument("--coefficient-bits must be in " +
                                std::to_string(kMinCoefficientBits) + ".." +
                                std::to_string(kMaxPairBits - 1));
  if (params.meanBits < 0 || params.meanBits > 24)
    throw std::invalid_argument("--mean-bits must be in 1..24");
  if (params.atomBits != 0 && (params.atomBits < kMinAtomBits || params.atomBits > kWideAtomBits))
    throw std::invalid_argument("--atom-bits must be in " + std::to_string(kMinAtomBits) + ".." +
                                std::to_string(kWideAtomBits));
}

}  // namespace

// Measured on the MRIs (docs/ksvd.md): at 0.25 and 0.5 bits per voxel 6-bit atoms coded ch2
// 0.6 dB closer than 16-bit ones (8: 0.35-0.5 dB); at 1 bit 8 matched 16 on ch2better where 6
// lost 0.4 dB; without a target 8 bits kept ch2's PSNR within 0.01 dB in a file 5% smaller.
int atomBitsFor(double bitsPerVoxel) { return bitsPerVoxel > 0 && bitsPerVoxel < 0.75 ? 6 : 8; }

// Measured on the MRIs (ch2 and ch2better, docs/ksvd.md): at a size target, fewer coefficient
// bits buy more pairs, which pays until the coefficients' rounding dominates the error: 6 bits
// were best at 0.25 bits per voxel, 7 at 0.5 (8 within 0.1 dB on ch2better) and 8 at 1.
int coefficientBitsFor(double bitsPerVoxel, int indexBits) {
  const int room = kMaxPairBits - indexBits;
  const int bits = bitsPerVoxel < 0.35   ? 6
                   : bitsPerVoxel < 0.75 ? 7
                   : bitsPerVoxel < 1.5  ? 8
                                         : room;
  return std::clamp(bits, std::min(kMinCoefficientBits, room), room);
}

std::vector<std::int16_t> learnDictionary(const Volume& volume, const Params& params,
                                          Progress& progress) {
  checkParams(params);
  if (volume.voxelCount() == 0) throw std::invalid_argument("ksvd codec: empty volume");
  EncodeStats stats;
  const std::unique_ptr<VolumeSource> source = memorySource(volume);
  return dispatchScalar(volume.type, [&](auto t) {
    return Encoder<decltype(t)>(*source, params, progress, stats).learnOnly();
  });
}

CompressedVolume encode(const VolumeSource& source, const Params& params, Progress& progress,
                        EncodeStats* statsOut) {
  checkParams(params);
  if (source.voxelCount() == 0) throw std::invalid_argument("ksvd codec: empty volume");
  EncodeStats stats;
  CompressedVolume out = dispatchScalar(source.type, [&](auto t) {
    return Encoder<decltype(t)>(source, params, progress, stats).run();
  });
  if (statsOut) *statsOut = stats;
  return out;
}

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* statsOut) {
  return encode(*memorySource(volume), params, progress, statsOut);
}

}  // namespace voxwall::codec::ksvd
