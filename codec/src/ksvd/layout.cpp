// The ksvd layout: every section checked against the header before anything reads it, the views
// the raycasters sample, and the decoder. The byte layout is documented in ksvd_codec.hpp.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>

#include "format.hpp"

namespace voxwall::codec::ksvd {

namespace {

// What reading the brick records into the render buffer, and checking the blocks' codes, needs
// and counts. Files of layout 2 are read where they lie; in files of layout 1 (a count byte per
// block, the DC atom's pair among the pairs) the counts are rewritten in unary as they are
// checked (`unary`), and the pairs are read where they lie.
struct BrickTables {
  ByteReader &bricks, &counts, &pairs;
  kernels::KsvdBits countBits, pairBits, dcBits;  // the file's sections
  kernels::KsvdBrick* brickOut;
  std::uint64_t perBrick;
  int layout, atoms, sparsity, indexBits, coefBits, meanBits;
  std::uint64_t codedBricks, pairCount;
  std::vector<std::byte>* unary;  // layout 1's counts, rewritten
  std::uint64_t codedSeen = 0;
  std::uint64_t pairSeen = 0;  // pairs read so far
  std::uint64_t countBit = 0;  // where the next block's unary count starts
};

std::string brickName(std::uint64_t b, std::size_t level) {
  std::string name = "brick " + std::to_string(b);
  if (level) name += " of level " + std::to_string(level);
  return name;
}

// Block j's pairs: at most `most`, within the header's count, each naming an atom there is.
void checkPairs(BrickTables& t, const std::string& which, int j, std::uint64_t count, int most,
                const char* what) {
  if (count > std::uint64_t(most))
    t.counts.fail(which + ": block " + std::to_string(j) + " has " + std::to_string(count) +
                  " pairs" + what + " (0.." + std::to_string(most) + ")");
  if (t.pairSeen + count > t.pairCount)
    t.pairs.fail("the blocks need more than the header's " + std::to_string(t.pairCount) +
                 " pairs");
  const int width = t.indexBits + t.coefBits;
  for (std::uint64_t p = t.pairSeen; p < t.pairSeen + count; ++p) {
    int atom = 0, q = 0;
    kernels::ksvdUnpackAt(t.pairBits, p * std::uint64_t(width), t.indexBits, t.coefBits, atom, q);
    if (atom >= t.atoms)
      t.pairs.fail("pair " + std::to_string(p) + " names atom " + std::to_string(atom) + " of " +
                   std::to_string(t.atoms));
  }
  t.pairSeen += count;
}

// Block j of a coded brick in a layout-2 file: its mean and unary count (both zero outside the
// volume) and its pairs (at most S - 1: S counts the mean).
void readBlock2(BrickTables& t, const std::string& which, int j, bool inGrid) {
  const std::uint32_t mean = t.dcBits.field(
      (t.codedSeen * t.perBrick + std::uint64_t(j)) * std::uint64_t(t.meanBits), t.meanBits);
  // Read as far as S ones: a longer run is an error, wherever it ends.
  std::uint64_t count = 0;
  while (count < std::uint64_t(t.sparsity) && t.countBits.field(t.countBit + count, 1)) ++count;
  if (!inGrid && (count != 0 || mean != 0))
    t.counts.fail(which + ": a block outside the volume has pairs");
  checkPairs(t, which, j, count, t.sparsity - 1, " besides its mean");
  t.countBit += count + 1;
}

// Block j of a coded brick in a layout-1 file: its count byte, rewritten in unary, and pairs.
void readBlock1(BrickTables& t, const std::string& which, int j, bool inGrid) {
  const int count = int(t.countBits.data[t.codedSeen * t.perBrick + std::uint64_t(j)]);
  if (!inGrid && count != 0) t.counts.fail(which + ": a block outside the volume has pairs");
  checkPairs(t, which, j, std::uint64_t(count), t.sparsity, "");
  for (int p = 0; p < count; ++p) appendBits(*t.unary, t.countBit, 1, 1);
  appendBits(*t.unary, t.countBit, 0, 1);
}

// Brick b of a level (grid g): its record, and, coded, its blocks' codes checked.
void readBrick(BrickTables& t, const Grid& g, std::size_t level, std::uint64_t firstBrick,
               std::uint64_t b) {
  kernels::KsvdBrick& out = t.brickOut[firstBrick + b];
  out.lo = t.bricks.get<float>(), out.hi = t.bricks.get<float>(), out.step = t.bricks.get<float>();
  const std::uint32_t index = t.bricks.get<std::uint32_t>();
  const std::string which = brickName(b, level);
  if (!std::isfinite(out.lo) || !std::isfinite(out.hi) || out.lo > out.hi)
    t.bricks.fail(which + ": bad value range");
  if (!std::isfinite(out.step) || out.step < 0) t.bricks.fail(which + ": bad coefficient step");
  if (out.step == 0) {
    if (index != kConstant || out.lo != out.hi)
      t.bricks.fail(which + ": a constant brick must have min == max and no coded index");
    return;
  }
  if (index != t.codedSeen)
    t.bricks.fail(which + ": coded index " + std::to_string(index) + ", expected " +
                  std::to_string(t.codedSeen));
  if (t.codedSeen >= t.codedBricks)
    t.bricks.fail("more coded bricks than the header's " + std::to_string(t.codedBricks));
  out.coded = index;
  out.firstPair = t.pairSeen;
  out.countBit = t.countBit;
  const glm::ivec3 bc = g.brickCoords(b);
  for (int j = 0; j < int(t.perBrick); ++j) {
    const bool inGrid = g.inGrid(g.blockOf(bc, j));
    if (t.layout == 1)
      readBlock1(t, which, j, inGrid);
    else
      readBlock2(t, which, j, inGrid);
  }
  ++t.codedSeen;
}

}  // namespace

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  cacheId_ = mintCacheIds();
  readParams(sections);
  readLevels(sections);
  buildRenderBuffer(sections);
}

void Layout::readParams(const SectionSet& sections) {
  ByteReader r(sections.get(kParams, "params"), sections.source, "section 'params'");
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
  // The coefficient's width: absent in files written before it was stored (3-byte pairs).
  coefBits_ = r.remaining() >= 4 ? int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 64))
                                 : 24 - indexBits_;
  // The layout of the blocks' codes: absent in files written before layout 2.
  layout_ = r.remaining() >= 4 ? int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 64)) : 1;
  if (layout_ != 1) meanBits_ = int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 64));
  // The atoms' width: absent in files written before it was stored (16 bits).
  if (layout_ != 1 && r.remaining() >= 4)
    atomBits_ = int(std::min<std::uint32_t>(r.get<std::uint32_t>(), 64));
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " bytes past the params");
  auto fail = [&](const std::string& what) { r.fail(what); };
  if (m_ != 4 && m_ != 6 && m_ != 8) fail("block side " + std::to_string(m_) + " (4, 6 or 8)");
  if (n_ != blocksPerBrick(m_))
    fail("blocks per brick " + std::to_string(n_) + " for block side " + std::to_string(m_));
  const int m = m_ * m_ * m_;
  if (k_ < 2 || k_ > kMaxAtoms) fail("atoms " + std::to_string(k_) + " (2..65536)");
  if (s_ < 1 || s_ > std::min(m, 255)) fail("sparsity " + std::to_string(s_));
  if (indexBits_ != indexBitsFor(k_))
    fail("index bits " + std::to_string(indexBits_) + " for " + std::to_string(k_) + " atoms");
  if (coefBits_ < kMinCoefficientBits || indexBits_ + coefBits_ > kMaxPairBits)
    fail("coefficient bits " + std::to_string(coefBits_) + " with " + std::to_string(indexBits_) +
         " index bits (" + std::to_string(kMinCoefficientBits) + ".." +
         std::to_string(kMaxPairBits) + " - index bits)");
  if (layout_ != 1 && layout_ != kLayout)
    fail("layout " + std::to_string(layout_) + " (1 or " + std::to_string(kLayout) + ")");
  if (layout_ != 1 && (meanBits_ < 1 || meanBits_ > 24))
    fail("mean bits " + std::to_string(meanBits_) + " (1..24)");
  if (atomBits_ < kMinAtomBits || atomBits_ > kWideAtomBits)
    fail("atom bits " + std::to_string(atomBits_) + " (" + std::to_string(kMinAtomBits) + ".." +
         std::to_string(kWideAtomBits) + ")");
  if (!(tolerance_ >= 0 && tolerance_ < 1)) fail("tolerance out of range");
  if (std::isnan(psnr_)) fail("PSNR is not a number");
}

// The levels: section 6, or level 0 alone in files from before the pyramid.
void Layout::readLevels(const SectionSet& sections) {
  std::vector<double> levelPsnr{psnr_};
  if (const auto it = sections.sections.find(kLevels); it != sections.sections.end()) {
    ByteReader lr(it->second, sections.source, "section 'levels'");
    const std::uint32_t count = lr.get<std::uint32_t>();
    if (count < 1 || count > std::uint32_t(kernels::kKsvdMaxLevels))
      lr.fail("levels " + std::to_string(count) + " (1.." +
              std::to_string(kernels::kKsvdMaxLevels) + ")");
    if (lr.remaining() != 8 * std::size_t(count))
      lr.fail(std::to_string(it->second.size()) + " bytes for " + std::to_string(count) +
              " levels");
    levelPsnr.resize(count);
    for (double& v : levelPsnr)
      if (std::isnan(v = lr.get<double>())) lr.fail("a level's PSNR is not a number");
  }
  std::uint64_t nBricks = 0, nBlocks = 0;
  for (std::size_t l = 0; l < levelPsnr.size(); ++l) {
    LevelInfo level;
    level.dims = (info_.dims - 1) / (1 << l) + 1;
    const Grid g(level.dims, m_);
    level.blocks = g.blocks, level.bricks = g.bricks;
    level.firstBrick = nBricks, level.firstBlock = nBlocks;
    level.psnr = levelPsnr[l];
    nBricks += g.brickCount(), nBlocks += g.blockCount();
    levels_.push_back(level);
  }
  if (codedBricks_ > nBricks)
    ByteReader(sections.get(kParams, "params"), sections.source, "section 'params'")
        .fail(std::to_string(codedBricks_) + " coded bricks of " + std::to_string(nBricks));
}

namespace {

// The sizes of the sections of the blocks' codes (counts, pairs and, in layout 2, means) of
// `codedBlocks` blocks and `pairs_` pairs.
struct CodeSizes {
  int layout_, pairBits, meanBits_;
  std::uint64_t codedBricks_, perBrick, pairs_;
  void check(const SectionSet& sections, ByteReader& cr, ByteReader& pr) const;
};

void CodeSizes::check(const SectionSet& sections, ByteReader& cr, ByteReader& pr) const {
  const std::uint64_t codedBlocks = codedBricks_ * perBrick;
  const auto countBytes = sections.get(kCounts, "counts");
  const std::uint64_t countsExpected =
      layout_ == 1 ? codedBlocks : (codedBlocks + pairs_ + 7) / 8;  // unary: a bit a pair and block
  if (pairs_ > (std::uint64_t(1) << 56) || countBytes.size() != countsExpected)
    cr.fail(std::to_string(countBytes.size()) + " bytes for " + std::to_string(codedBricks_) +
            " coded bricks of " + std::to_string(perBrick) + " blocks" +
            (layout_ == 1 ? "" : " and " + std::to_string(pairs_) + " pairs"));
  const auto pairBytes = sections.get(kPairs, "pairs");
  if (pairBytes.size() != pairStreamBytes(pairs_, pairBits))
    pr.fail(std::to_string(pairBytes.size()) + " bytes for " + std::to_string(pairs_) +
            " pairs of " + std::to_string(pairBits) + " bits");
  if (layout_ == 1) return;
  const auto dcBytes = sections.get(kDc, "dc");
  if (dcBytes.size() != (codedBlocks * std::uint64_t(meanBits_) + 7) / 8)
    ByteReader(dcBytes, sections.source, "section 'dc'")
        .fail(std::to_string(dcBytes.size()) + " bytes for " + std::to_string(codedBlocks) +
              " means of " + std::to_string(meanBits_) + " bits");
}

}  // namespace

// The render buffer: float atoms and brick records (levels one after the other), each section's
// size checked first; the blocks' codes stay in their sections (layout 1's counts are rewritten
// in unary).
void Layout::buildRenderBuffer(const SectionSet& sections) {
  const std::string& src = sections.source;
  const int m = m_ * m_ * m_;
  const Grid last(levels_.back().dims, m_);
  const std::uint64_t nBricks = levels_.back().firstBrick + last.brickCount();
  const std::uint64_t perBrick = std::uint64_t(last.blocksPerBrick());
  const auto dictBytes = sections.get(kDictionary, "dictionary");
  std::vector<float> dictionary;
  try {
    dictionary = dictionaryValues(dictBytes, std::uint64_t(k_), m, atomBits_);
  } catch (const std::invalid_argument& e) {
    ByteReader(dictBytes, src, "section 'dictionary'").fail(e.what());
  }
  const auto brickBytes = sections.get(kBricks, "bricks");
  ByteReader br(brickBytes, src, "section 'bricks'");
  if (brickBytes.size() != nBricks * 16)
    br.fail(std::to_string(brickBytes.size()) + " bytes for " + std::to_string(nBricks) +
            " bricks of 16 bytes");
  const auto countBytes = sections.get(kCounts, "counts");
  ByteReader cr(countBytes, src, "section 'counts'");
  const auto pairBytes = sections.get(kPairs, "pairs");
  ByteReader pr(pairBytes, src, "section 'pairs'");
  const auto dcBytes = layout_ == 1 ? std::span<const std::byte>{} : sections.get(kDc, "dc");
  CodeSizes{layout_, indexBits_ + coefBits_, meanBits_, codedBricks_, perBrick, pairs_}.check(
      sections, cr, pr);

  auto align8 = [](std::uint64_t v) { return (v + 7) / 8 * 8; };
  atomsAt_ = 0;
  bricksAt_ = align8(std::uint64_t(k_) * std::uint64_t(m) * 4);
  render_.assign(align8(bricksAt_ + nBricks * sizeof(kernels::KsvdBrick)), std::byte{0});
  std::memcpy(render_.data() + atomsAt_, dictionary.data(), dictionary.size() * sizeof(float));
  auto bits = [](std::span<const std::byte> b) {
    return kernels::KsvdBits{reinterpret_cast<const std::uint8_t*>(b.data()), b.size()};
  };
  auto unary = layout_ == 1 ? std::make_shared<std::vector<std::byte>>() : nullptr;
  BrickTables t{br,
                cr,
                pr,
                bits(countBytes),
                bits(pairBytes),
                bits(dcBytes),
                reinterpret_cast<kernels::KsvdBrick*>(render_.data() + bricksAt_),
                perBrick,
                layout_,
                k_,
                s_,
                indexBits_,
                coefBits_,
                meanBits_,
                codedBricks_,
                pairs_,
                unary.get()};
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    const Grid g(levels_[l].dims, m_);
    for (std::uint64_t b = 0; b < g.brickCount(); ++b) readBrick(t, g, l, levels_[l].firstBrick, b);
  }
  if (t.codedSeen != codedBricks_)
    br.fail(std::to_string(t.codedSeen) + " coded bricks, the header says " +
            std::to_string(codedBricks_));
  if (t.pairSeen != pairs_)
    pr.fail(std::to_string(t.pairSeen) + " pairs used, the header says " + std::to_string(pairs_));
  pairBytes_ = pairBytes, countBytes_ = countBytes, dcBytes_ = dcBytes;
  if (unary) unary_ = unary, countBytes_ = *unary;
  // Where joinedBytes() puts the streams, each followed by 8 bytes of slack.
  pairsAt_ = render_.size();
  countsAt_ = align8(pairsAt_ + pairBytes_.size() + 8);
  dcAt_ = align8(countsAt_ + countBytes_.size() + 8);
  joinedSize_ = align8(dcAt_ + dcBytes_.size() + 8);
}

std::vector<std::byte> Layout::joinedBytes() const {
  std::vector<std::byte> out(joinedSize_, std::byte{0});
  std::memcpy(out.data(), render_.data(), render_.size());
  const std::pair<std::uint64_t, std::span<const std::byte>> streams[] = {
      {pairsAt_, pairBytes_}, {countsAt_, countBytes_}, {dcAt_, dcBytes_}};
  for (const auto& [at, bytes] : streams)
    if (!bytes.empty()) std::memcpy(out.data() + at, bytes.data(), bytes.size());
  return out;
}

std::uint64_t Layout::bricks() const {
  std::uint64_t n = 0;
  for (const LevelInfo& l : levels_)
    n += std::uint64_t(l.bricks.x) * std::uint64_t(l.bricks.y) * std::uint64_t(l.bricks.z);
  return n;
}

template <int Side>
kernels::KsvdView<Side> Layout::view(const std::byte* base) const {
  if (Side != m_) throw std::logic_error("ksvd view of the wrong block side");
  kernels::KsvdView<Side> v;
  v.levels = int(levels_.size());
  v.dimX = info_.dims.x, v.dimY = info_.dims.y, v.dimZ = info_.dims.z;
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    const LevelInfo& level = levels_[l];
    auto& lv = v.level[l];
    lv.setDims(level.dims.x, level.dims.y, level.dims.z);
    lv.cacheId = cacheId_;
    auto& d = lv.decoder;
    d.data = reinterpret_cast<const std::uint8_t*>(base ? base : render_.data());
    auto stream = [&](std::uint64_t at, std::span<const std::byte> bytes) {
      return kernels::KsvdBits{
          base ? d.data + at : reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()};
    };
    d.pairs = stream(pairsAt_, pairBytes_);
    d.counts = stream(countsAt_, countBytes_);
    d.dc = stream(dcAt_, dcBytes_);
    d.dcBits = meanBits_;
    d.dcLevels = meanBits_ > 0 ? float((1u << meanBits_) - 1u) : 1.0f;
    d.atomsAt = atomsAt_;
    d.bricksAt = bricksAt_ + level.firstBrick * sizeof(kernels::KsvdBrick);
    d.keyBase = level.firstBlock;
    d.blocksX = level.blocks.x, d.blocksY = level.blocks.y;
    d.bricksX = level.bricks.x, d.bricksY = level.bricks.y;
    d.blocksPerBrick = n_, d.indexBits = indexBits_, d.coefBits = coefBits_;
    d.integral = info_.type != ScalarType::Float32;
  }
  return v;
}
template kernels::KsvdView<4> Layout::view<4>(const std::byte*) const;
template kernels::KsvdView<6> Layout::view<6>(const std::byte*) const;
template kernels::KsvdView<8> Layout::view<8>(const std::byte*) const;

RangeGrid Layout::rangeGrid() const {
  return withView([&](const auto& v) { return brickRangeGrid(v.level[0], info_.type); });
}

Volume Layout::decode() const {
  return withView(
      [&](const auto& v) { return decodeBricks(v.level[0], info_.type, info_.spacing); });
}

Volume Layout::decodeLevel(int level) const {
  if (level < 0 || level >= levels()) throw std::out_of_range("ksvd level");
  return withView([&](const auto& v) {
    return decodeBricks(v.level[level], ScalarType::Float32, info_.spacing * double(1 << level));
  });
}

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  return Layout(info, sections).decode();
}

}  // namespace voxwall::codec::ksvd
