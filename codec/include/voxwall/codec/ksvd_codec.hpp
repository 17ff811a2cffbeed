// The `ksvd` codec: sparse coding of voxel blocks over a learned dictionary (Gobbetti, Iglesias
// Guitian and Marton, "COVRA: A compression-domain output-sensitive volume rendering
// architecture based on a sparse representation of voxel blocks", 2012, sections 3-5).
//
// The volume is cut into bricks of N^3 blocks of M^3 voxels (M = 4, 6 or 8; N = 8, 5 or 4, so a
// brick is about 32 voxels wide; the border is padded by repeating the edge voxel). A brick
// whose values span at most the tolerance (x the volume's range) is constant and stores its
// mean; every other brick codes each block y, taken relative to the brick's minimum, as a sparse
// combination of dictionary atoms: y ~ sum of c_i d[a_i] with at most S pairs (a_i, c_i). The
// first atom is the constant (DC) atom 1/sqrt(M^3) and takes part in every block's code; the
// others are learned by K-SVD on a coreset of the volume's blocks (docs/ksvd.md).
//
// Multiresolution: the file holds a pyramid of levels coded with the same dictionary. Level 0 is
// the volume; level l (((dim - 1) >> l) + 1 voxels per axis) is the mean of the 2x2x2 voxels of
// level l - 1 below each of its voxels (clamped at the far faces). Each level is bricked as
// above; sections 3-5 hold level 0's bricks, blocks and pairs, then level 1's, and so on.
// `render --lod` samples the coarsest level whose voxels are no wider than a pixel's footprint.
//
// Values are decoded as floats: brickMin + mean + sum(q_i * step * d[a_i]), clamped to the brick's
// [min, max]; integer types round to the nearest integer of the type. Any scalar type is
// accepted (uint8, uint16, int16, float32).
//
// Sections (ids within the codec's own, KsvdCodecEntry::kId), little-endian:
//   1 params:
//       u32 M (4, 6, 8)        u32 N (blocks per brick side, 1..8)
//       u32 K (atoms, 2..2^16) u32 S (pairs per block at most, 1..min(M^3, 255))
//       u32 indexBits (bits of the atom index in a pair: ceil(log2 K), 1..16)
//       u32 iterations (K-SVD iterations run)
//       u64 codedBricks        u64 pairs (in section 5)   u64 coreset (training blocks)
//       f64 tolerance (per-block RMS error target, relative to the value range; 0: none;
//           with a size target, the tolerance that met it)
//       f64 psnr of the decoded volume against the input in dB (+inf when exact)
//       u32 coefBits (bits of a pair's quantized coefficient: 2..24 - indexBits; absent in files
//           written before it was stored, whose pairs are 3 bytes: 24 - indexBits)
//       u32 layout of the blocks' codes, 1 or 2 (absent in files of layout 1)
//       u32 meanBits (layout 2 only: bits of a block's mean, 1..24)
//       u32 atomBits (bits of an atom's value, 4..16; absent: 16)
//   2 dictionary: K atoms of M^3 values (x fastest). 16 bits: i16, each value x 32767, rounded.
//       Fewer: K f32 scales (an atom's largest magnitude over 2^(atomBits - 1) - 1), then every
//       value of every atom in atomBits bits (two's complement, LSB-first, the last byte padded
//       with zero bits), the value q x its atom's scale. The encoder codes with the atoms as
//       stored.
//   3 bricks: per brick (x fastest), 16 bytes: f32 min, f32 max, f32 step (the coefficient
//       quantum; 0 for a constant brick, whose every voxel is min == max), u32 coded index (the
//       number of coded bricks before it; 0xFFFFFFFF for a constant brick)
//   Layout 2 (what the encoder writes): a block's code is its mean, always there, and its pairs
//   of learned atoms (at most S - 1).
//   7 dc: per coded brick and block (blocks x fastest), the block's mean above its brick's
//       minimum, quantized to meanBits bits (unsigned) in steps of (max - min) / (2^meanBits - 1),
//       packed LSB-first; 0 past the volume's edge
//   4 counts: per coded brick and block, its number of pairs in unary (that many one bits, then
//       a zero bit), LSB-first, bricks one after the other; 0 past the edge
//   5 pairs: per coded brick, block and pair, indexBits + coefBits bits packed LSB-first (pair p
//       from bit p x (indexBits + coefBits); the last byte padded with zero bits): the atom index
//       in the low indexBits bits, the quantized coefficient (two's complement) in the coefBits
//       above
//   Layout 1 (read, not written): no section 7; 4 counts: per coded brick, its N^3 blocks' pair
//       counts (u8, 0..S); 5 pairs: every pair of every block, the DC atom's first (its
//       coefficient x the DC atom is the block's mean). A pair whose coefficient quantizes to 0
//       is left out.
//   6 levels (absent in files from before the pyramid, which hold level 0 only):
//       u32 levels (1..8), then per level f64 PSNR of the decoded level against that level of
//       the input's pyramid, in dB (peak = the level's value range; +inf when exact)
// Coded indices, counts and pairs run on across levels: the coded bricks of all levels, in level
// order, then brick order.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/ksvd_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::ksvd {

enum SectionId : std::uint32_t {
  kParams = 1,
  kDictionary = 2,
  kBricks = 3,
  kCounts = 4,
  kPairs = 5,
  kLevels = 6,
  kDc = 7
};

// The layout of the blocks' codes the encoder writes (a params field): 2, each block's mean apart
// from its pairs and unary counts; files of layout 1 are read too.
inline constexpr int kLayout = 2;

// An atom's stored value: 16 bits in every file before the width was stored; fewer since, with a
// scale per atom (atomBitsFor: a smaller dictionary, for more pairs in the same file).
inline constexpr int kWideAtomBits = 16, kMinAtomBits = 4;

struct Params {
  int blockSide = 6;              // M
  int atoms = 1024;               // K (fewer when the volume has few blocks: see encode)
  int sparsity = 8;               // S
  double tolerance = 0;           // > 0: stop a block's code at this RMS error (x the value range)
  double coreset = 0;             // training blocks: > 1 a count, (0, 1] a fraction, 0 the default
  double targetBitsPerVoxel = 0;  // > 0: the smallest tolerance whose file fits this size
  // Bits of a pair's quantized coefficient (2..24 - index bits); 0: 24 - index bits, or with a
  // size target the width that measured best at that rate (coefficientBitsFor).
  int coefficientBits = 0;
  int meanBits = 0;     // bits of a block's mean (1..24); 0: coefficientBits - 1
  int atomBits = 0;     // bits of an atom's stored value (4..16); 0: atomBitsFor the target
  int iterations = 25;  // K-SVD iterations
  int levels = 0;   // pyramid levels (1: level 0 only); 0: until a level fits in one brick, <= 8
  int threads = 0;  // 0: every usable core
  std::uint64_t seed = 1;  // coreset and dictionary initialisation
  // A dictionary to code with instead of learning one (its atoms at 16 bits, as section 2 of a
  // file with 16-bit atoms holds them: a series' steps share one, each narrowing it to atomBits
  // the same way); its atom count replaces `atoms`.
  std::shared_ptr<const std::vector<std::int16_t>> dictionary;
};

// What the encoder did, for the CLI and benchmarks.
struct EncodeStats {
  // Over every level. Coded blocks: the blocks of coded bricks (what the coreset samples).
  std::uint64_t bricks = 0, constantBricks = 0, codedBlocks = 0, pairs = 0, coreset = 0;
  int levels = 1;
  std::uint64_t levelPairs = 0;   // pairs of the levels above 0
  std::vector<double> levelPsnr;  // per level, as section 6
  int atoms = 0, sparsity = 0, iterations = 0, atomBits = 0;
  int indexBits = 0, coefficientBits = 0;  // a pair's two fields
  int trainSparsity = 0;                   // the sparsity K-SVD trained with
  double psnr = 0;
  double trainSeconds = 0, codeSeconds = 0;
  double trainingRmse = 0;  // weighted RMS error on the coreset after training (x value range)
  std::uint64_t dictionaryBytes = 0, brickBytes = 0, countBytes = 0, pairBytes = 0;
};

// The dictionary encode() would learn on `volume` (section 2's atoms), learned and nothing coded:
// on a volume of several steps stacked, a coreset drawn from every step (as COVRA trains one
// dictionary for a time-varying volume).
std::vector<std::int16_t> learnDictionary(const Volume& volume, const Params& params,
                                          Progress& progress);

// A size target below the smallest file the settings can make (with a smaller block side, or
// fewer atoms, a smaller one may exist).
struct SizeTargetTooSmall : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

// Throws std::invalid_argument for bad parameters (SizeTargetTooSmall for a size target the
// settings cannot meet). A source that streams is read a row of bricks (N x M slices) at a time,
// once per pass (the pyramid, the bricking, the coreset's three, each coding pass of a size
// target's search, the PSNR); the file equals the one of the same volume in memory.
CompressedVolume encode(const VolumeSource& source, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);
CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);

// Full reconstruction, in the volume's scalar type.
Volume decode(const VolumeInfo& info, const SectionSet& sections);

// ---- building blocks, exposed for tests -------------------------------------------------

// Blocks per brick side for block side M.
int blocksPerBrick(int blockSide);

// A dictionary: K atoms of m values, atom-major. Atom 0 is the DC atom.
struct Dictionary {
  int m = 0, atoms = 0;
  std::vector<float> values;  // atoms x m
  const float* atom(int k) const { return values.data() + std::size_t(k) * std::size_t(m); }
  float* atom(int k) { return values.data() + std::size_t(k) * std::size_t(m); }
};

// A sparse code: atom indices and coefficients (the DC atom first) and the squared residual.
struct SparseCode {
  std::vector<int> atoms;
  std::vector<float> coefficients;
  double residual2 = 0;
};

// Orthogonal matching pursuit with the DC atom forced first and an incremental Cholesky
// factorisation of the chosen atoms' Gram matrix: at most `sparsity` atoms; stops early when
// the squared residual is at most `maxResidual2`. `dictionary`'s atoms must be unit-norm.
SparseCode ompCode(const Dictionary& dictionary, std::span<const float> y, int sparsity,
                   double maxResidual2 = 0);

// Training blocks, already weighted (each block times its weight).
struct TrainingSet {
  int m = 0;
  std::vector<float> blocks;          // count x m
  std::vector<float> weights;         // per block
  std::vector<std::uint64_t> source;  // the block's index in the candidate order
  std::size_t count() const { return weights.size(); }
  const float* block(std::size_t i) const { return blocks.data() + i * std::size_t(m); }
};

// The coreset of section 4.3: importance = a block's standard deviation; a 512-bin importance
// histogram from two streaming passes; per-bin budgets proportional to importance, fitted to
// `size` (saturated bins take every block); reservoir sampling per bin; each block weighted by
// sqrt(Q_q / B_q). `block(i, out)` writes candidate block i (m values).
TrainingSet buildCoreset(std::uint64_t candidates, int m,
                         const std::function<void(std::uint64_t, float*)>& block,
                         std::uint64_t size, std::uint64_t seed, Progress& progress);

struct TrainParams {
  int atoms = 1024, sparsity = 8, iterations = 25, threads = 0;
  double maxResidual2 = 0;  // per block, as ompCode
  std::uint64_t seed = 1;
};
// Approximate K-SVD (Rubinstein et al.): sparse coding by ompCode, then each atom but the DC
// updated by one power iteration on its residual, kept zero-mean and unit-norm; unused atoms are
// replaced by the worst-represented block. `afterIteration` (if set) sees the dictionary after
// every iteration. Returns the dictionary; `rmse` receives the final weighted RMS error.
Dictionary trainDictionary(const TrainingSet& set, const TrainParams& params, Progress& progress,
                           double* rmse = nullptr,
                           const std::function<void(int, const Dictionary&)>& afterIteration = {});

// A pair of indexBits + coefBits bits: the index in the low indexBits bits, q in the coefBits
// above (|q| <= maxQuantized(coefBits)); throws std::invalid_argument when either does not fit.
std::uint32_t packPair(int atom, int q, int indexBits, int coefBits);
// Appends a packed pair to a pair stream of pairBits-bit pairs (the pairs section's layout) that
// holds `pairs` pairs so far; the stream's size stays a whole number of bytes.
void appendPair(std::vector<std::byte>& stream, std::uint64_t pairs, std::uint32_t word,
                int pairBits);
// Appends the low `width` (<= 32) bits of `value` to a bit stream (LSB-first) that holds `bits`
// bits so far, and advances `bits`; the stream's size stays a whole number of bytes.
void appendBits(std::vector<std::byte>& stream, std::uint64_t& bits, std::uint32_t value,
                int width);
// Section 2's size, and its bytes, for K atoms of m values at atomBits bits (the atoms quantized
// as the file stores them); and the values a section holds (std::invalid_argument when its size
// or a scale is wrong).
std::uint64_t dictionaryBytes(std::uint64_t atoms, int m, int atomBits);
std::vector<std::byte> dictionarySection(std::span<const float> values, int m, int atomBits);
std::vector<float> dictionaryValues(std::span<const std::byte> section, std::uint64_t atoms, int m,
                                    int atomBits);
// The largest |q| a coefficient of coefBits bits holds.
inline int maxQuantized(int coefBits) { return (1 << (coefBits - 1)) - 1; }
// The atoms' width a size target of `bitsPerVoxel` (0: none) stores when none is given: 6 bits
// below 0.75 bits per voxel, else 8.
int atomBitsFor(double bitsPerVoxel);
// The coefficient width a size target of `bitsPerVoxel` codes with when none is given.
int coefficientBitsFor(double bitsPerVoxel, int indexBits);

// The sections of a ksvd-coded volume, validated, and the render buffer built from them.
class Layout {
 public:
  Layout(const VolumeInfo& info, const SectionSet& sections);
  int blockSide() const { return m_; }
  int atoms() const { return k_; }
  int sparsity() const { return s_; }
  int iterations() const { return iterations_; }
  int indexBits() const { return indexBits_; }
  int coefficientBits() const { return coefBits_; }
  int layout() const { return layout_; }
  int meanBits() const { return meanBits_; }  // 0 in layout 1
  int atomBits() const { return atomBits_; }
  std::uint64_t codedBricks() const { return codedBricks_; }
  std::uint64_t pairs() const { return pairs_; }  // in the pairs section
  std::uint64_t coreset() const { return coreset_; }
  double tolerance() const { return tolerance_; }
  double psnr() const { return psnr_; }
  std::uint64_t bricks() const;  // of every level
  int levels() const { return int(levels_.size()); }
  glm::ivec3 levelDims(int level) const { return levels_.at(std::size_t(level)).dims; }
  glm::ivec3 levelBricks(int level) const { return levels_.at(std::size_t(level)).bricks; }
  double levelPsnr(int level) const { return levels_.at(std::size_t(level)).psnr; }
  // The render buffer (atoms, bricks) and the blocks' three code streams (pairs, counts, dc)
  // joined, for a device; a host view reads the streams where their sections lie.
  std::vector<std::byte> joinedBytes() const;
  // The bytes a host view holds beside the file's sections (the render buffer).
  std::uint64_t renderBufferBytes() const { return render_.size() + (unary_ ? unary_->size() : 0); }
  // The view for this block side, over joinedBytes() at `base` (the host view when null).
  template <int Side>
  kernels::KsvdView<Side> view(const std::byte* base = nullptr) const;
  // Calls f(view<M>(base)) for the file's block side M.
  template <class F>
  decltype(auto) withView(F&& f, const std::byte* base = nullptr) const {
    switch (m_) {
      case 4:
        return f(view<4>(base));
      case 6:
        return f(view<6>(base));
      default:
        return f(view<8>(base));
    }
  }
  RangeGrid rangeGrid() const;
  Volume decode() const;                // level 0, in the volume's type
  Volume decodeLevel(int level) const;  // float32

 private:
  struct LevelInfo {
    glm::ivec3 dims{}, blocks{}, bricks{};
    std::uint64_t firstBrick = 0, firstBlock = 0;  // bricks and blocks of the levels before
    double psnr = 0;
  };
  // The constructor's steps: the header, the levels, then the render buffer from the sections.
  void readParams(const SectionSet& sections);
  void readLevels(const SectionSet& sections);
  void buildRenderBuffer(const SectionSet& sections);
  VolumeInfo info_;
  int m_ = 6, n_ = 5, k_ = 0, s_ = 0, indexBits_ = 0, coefBits_ = 0, iterations_ = 0, layout_ = 1;
  int meanBits_ = 0, atomBits_ = kWideAtomBits;
  std::uint64_t codedBricks_ = 0, pairs_ = 0, coreset_ = 0;
  double tolerance_ = 0, psnr_ = 0;
  std::vector<LevelInfo> levels_;
  std::vector<std::byte> render_;
  // The code streams: sections 'pairs', 'counts' and 'dc' (layout 1: no 'dc', and its counts
  // rewritten in unary, held by unary_ and shared by copies).
  std::span<const std::byte> pairBytes_, countBytes_, dcBytes_;
  std::shared_ptr<const std::vector<std::byte>> unary_;
  // Offsets in the render buffer, and where joinedBytes() puts the streams.
  std::uint64_t atomsAt_ = 0, bricksAt_ = 0, pairsAt_ = 0, countsAt_ = 0, dcAt_ = 0;
  std::uint64_t joinedSize_ = 0;
  std::uint64_t cacheId_ = 0;
};

// The codec's registry entry (registry.hpp).
struct KsvdCodecEntry {
  static constexpr CodecId kId{4};  // stored in files: never reused
  static constexpr std::string_view kName = "ksvd";
  using Views = ViewList<kernels::KsvdView4, kernels::KsvdView6, kernels::KsvdView8>;
  static const Codec& instance();
};

}  // namespace voxwall::codec::ksvd
