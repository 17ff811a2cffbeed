// The `tvq` codec: transform vector quantization of 4^3 blocks (Fout and Ma, "Transform Coding
// for Hardware-Accelerated Volume Rendering", IEEE TVCG 2007). docs/tvq.md gives our reading of
// each step of the paper.
//
// Every block's 64 voxels are transformed by an orthonormal basis (the KLT learned from the
// volume's blocks, or the 3D DCT). Coefficient 0 is the block's mean (basis vector 0 is the
// constant 1/8 in both), stored per block by a uniform scalar quantizer. The other 63 fall in the
// eight zones of Figure 3 (zone bits: high half of the x, y, z frequencies), grouped into the
// lowpass (zone 0, 7 coefficients), bandpass (zones 1, 2, 4: 24) and highpass (zones 3, 5, 6, 7:
// 32) partitions. A block takes the cheapest class of Figure 5 whose retained zones reconstruct
// it within the fidelity threshold (ZERO, LP, BPx, BPy, BPz, BPxyz, HPxy, HPxz, HPyz, HPxyz).
// Each class has its own vector quantizer ("chapter") per partition it uses; the chapters of a
// partition are concatenated into one global codebook whose index 0 is the zero vector, so a
// block's record is its quantized mean and three codes, whatever its class. The volume is cut
// into sub-volumes of S^3 blocks (section 6.2), each with its own codebooks and bit allocation.
// A ZERO-class block whose quantized mean is its sub-volume's most common one is not stored at
// all: an occupancy bit says so (the MRI's empty space costs 1.5 bits per block).
//
// Sections (ids within the codec's own, TvqCodecEntry::kId), little-endian:
//   1 params (88 bytes):
//       u32 transform (1 KLT, 2 DCT)   u32 S (sub-volume side in blocks, 1..256)
//       u32 dcBits (1..16)             u32 classified (1: the ten classes; 0: every coded block
//                                          is HPxyz, the paper's "without classification")
//       u32 code bits (the three codes' bits per coded block asked for, 0..39) u32 reserved (0)
//       f64 fidelity (RMS truncation error a class may leave, x the value range)
//       f64 dcLo, f64 dcStep (a mean is dcLo + q x dcStep, q < 2^dcBits; dcStep > 0)
//       f64 PSNR per progressive level, 4 (mean only, + lowpass, + bandpass, all; dB, peak =
//           the value range, +inf when exact), measured on the decoded volume
//       u64 sub-volumes (the grid's count, checked)
//   2 basis: 64 x 64 f32, row k = basis vector k over the block's voxels (x fastest); row 0 is
//       1/8 everywhere; then 64 u8: the zone (0..7) of each coefficient (coefficient 0: zone 0);
//       zones 0 / 1, 2, 4 / 3, 5, 6, 7 hold 8 / 8 each / 8 each coefficients
//   3 sub-volumes: per sub-volume (x fastest), 112 bytes:
//       u8 code bits per partition (LP, BP, HP; 0..13), u8 reserved (0)
//       u32 background q (the mean of every uncoded block)   u64 coded blocks
//       f32 codebook scale per partition (a stored i16 v is the coefficient v x scale)
//       u32 chapter sizes: 9 for LP (classes LP..HPxyz), 8 for BP (BPx..HPxyz), 4 for HP
//           (HPxy..HPxyz); 1 + the sizes of a partition <= 2^(its code bits)
//   4 codebooks: per sub-volume, partition and chapter, its codevectors' coefficients as i16
//       (only the coefficients of the chapter's zones, in coefficient order)
//   5 occupancy: per sub-volume, ceil(blocks / 64) u64 words, bit i = local block i (x
//       fastest within the sub-volume) is coded; popcount = coded blocks
//   6 records: per sub-volume, from a byte boundary, coded blocks x (dcBits + the three code
//       bits) bits, LSB first: q, then the LP, BP and HP codes (global codebook indices)
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/tvq_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec::tvq {

enum SectionId : std::uint32_t {
  kParams = 1,
  kBasis = 2,
  kSubvolumes = 3,
  kCodebooks = 4,
  kOccupancy = 5,
  kRecords = 6
};

enum class Transform : std::uint32_t { Klt = 1, Dct = 2 };

inline constexpr int kBlockVoxels = 64;
inline constexpr int kClasses = 10;
inline constexpr int kMaxCodeBits = 13;  // per partition
inline constexpr int kProgressiveLevels = 4;
inline constexpr int kMaxSubvolumeBlocks = 256;  // a sub-volume's side in blocks at most

// The classes of Figure 5, cheapest first.
enum Class : int {
  kZero = 0,
  kLp = 1,
  kBpX = 2,
  kBpY = 3,
  kBpZ = 4,
  kBpXyz = 5,
  kHpXy = 6,
  kHpXz = 7,
  kHpYz = 8,
  kHpXyz = 9
};
const char* className(int c);
// The zones (bit z set: zone z) a class keeps; ZERO keeps none, not even the lowpass zone.
std::uint8_t classZones(int c);
// The partition of zone z: 0 lowpass, 1 bandpass, 2 highpass.
inline int zonePartition(int zone) {
  return zone == 0 ? 0 : (__builtin_popcount(unsigned(zone)) == 1 ? 1 : 2);
}
// The first class with a chapter in partition p, and how many chapters p has (9, 8, 4).
inline int firstChapterClass(int p) { return p == 0 ? kLp : (p == 1 ? kBpX : kHpXy); }
inline int chapterCount(int p) { return kClasses - firstChapterClass(p); }

struct Params {
  Transform transform = Transform::Klt;
  int codeBits = 20;              // the three codes' bits per coded block (split by allocation)
  double targetBitsPerVoxel = 0;  // > 0: the largest codeBits whose file fits this size
  int dcBits = 8;                 // the block mean's quantizer
  int subvolumeVoxels = 256;      // sub-volume side in voxels (a multiple of 4, 4..1024)
  double fidelity = 0.005;        // RMS truncation error a class may leave (x the value range)
  bool classified = true;         // false: every coded block is HPxyz
  int iterations = 10;            // LBG iterations after the last split
  // LBG trains on at most max(this, 16 x the codevectors) of a chapter's blocks (a random sample).
  std::uint64_t trainingVectors = 32768;
  int threads = 0;
  std::uint64_t seed = 1;
};

struct EncodeStats {
  std::uint64_t blocks = 0, coded = 0;                // every block; those with a record
  std::array<std::uint64_t, kClasses> classBlocks{};  // per class (ZERO: coded and uncoded)
  int subvolumes = 0;
  int codeBits = 0;                      // asked for (what --bits-per-voxel chose)
  std::array<double, 3> meanCodeBits{};  // LP, BP, HP bits, mean over sub-volumes
  std::uint64_t codebookBytes = 0, recordBytes = 0, occupancyBytes = 0;
  std::array<double, kProgressiveLevels> levelPsnr{};
  double transformSeconds = 0, classifySeconds = 0, trainSeconds = 0;  // trainSeconds: LBG + coding
};

// Throws std::invalid_argument for bad parameters or a target no file meets.
CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);
// The same from a volume read a row of sub-volumes (or a batch of blocks for the KLT) at a time:
// the same bytes.
CompressedVolume encode(const VolumeSource& volume, const Params& params, Progress& progress,
                        EncodeStats* stats = nullptr);

// Full reconstruction (every partition), in the volume's scalar type.
Volume decode(const VolumeInfo& info, const SectionSet& sections);

// ---- building blocks, exposed for tests -------------------------------------------------

// An orthonormal basis of the 64 voxels of a block: row k is basis vector k; row 0 is the
// constant 1/8; zone[k] is coefficient k's zone.
struct Basis {
  std::array<float, kBlockVoxels * kBlockVoxels> rows{};
  std::array<std::uint8_t, kBlockVoxels> zone{};
  const float* row(int k) const { return rows.data() + k * kBlockVoxels; }
  // c = B x and x = B^T c.
  void forward(const float* x, float* c) const;
  void inverse(const float* c, float* x) const;
};

// The 3D DCT-II (orthonormal): coefficient u + 4v + 16w, zone (u >= 2) | (v >= 2) << 1 |
// (w >= 2) << 2.
Basis dctBasis();
// The KLT of the blocks whose 64 voxels `block(i, out)` writes (i < count): basis vector 0 the
// constant, the others the eigenvectors of the mean-removed blocks' covariance within the
// constant's orthogonal complement, by decreasing eigenvalue; each takes the zone in which the
// DCT finds most of its energy, the zones keeping the DCT's sizes (docs/tvq.md). Blocks are read
// in batches of consecutive indices; `prepare(first, end)`, when given, runs before the blocks
// first .. end-1 are read (a streaming encoder loads their slices).
Basis kltBasis(std::uint64_t count, const std::function<void(std::uint64_t, float*)>& block,
               int threads, Progress& progress,
               const std::function<void(std::uint64_t, std::uint64_t)>& prepare = {});

// The cheapest class whose kept zones leave a squared error of at most maxError2 (over the 64
// voxels) of the coefficients `c` (coefficient 0 ignored: the mean is coded apart).
int classify(const Basis& basis, const float* c, double maxError2, bool classified);

// The sections of a tvq-coded volume, validated, and what the view reads. On the host the view
// reads the occupancy and records where the sections lie (a mapped file's pages come in where
// rays go) and each sub-volume's associated codebooks are made the first time a block of it is
// decoded, so a rank holds the codebooks of the sub-volumes its rays reach. A device gets all of
// it joined in one buffer (joinedBytes).
class Layout {
 public:
  Layout(const VolumeInfo& info, const SectionSet& sections);
  ~Layout();
  Layout(const Layout&) = delete;
  Layout& operator=(const Layout&) = delete;
  Transform transform() const { return transform_; }
  bool classified() const { return classified_; }
  int dcBits() const { return dcBits_; }
  int codeBits() const { return codeBits_; }
  int subvolumeBlocks() const { return s_; }
  int subvolumes() const { return int(subvolumes_.size()); }
  double fidelity() const { return fidelity_; }
  double levelPsnr(int level) const { return levelPsnr_.at(std::size_t(level)); }
  std::uint64_t codedBlocks() const { return coded_; }
  std::uint64_t codevectors(int partition) const { return codevectors_[std::size_t(partition)]; }
  const Basis& basis() const { return basis_; }
  // Everything the view reads, in one buffer for a device: the sub-volume table, every
  // sub-volume's associated codebooks, the occupancy ranks, the occupancy words and the records.
  std::vector<std::byte> joinedBytes() const;
  // The bytes of every sub-volume's associated codebooks (what a host view holds once its rays
  // have reached every sub-volume), and of those made so far.
  std::uint64_t associatedBytes() const { return booksBytes_; }
  std::uint64_t associatedResidentBytes() const;
  // Frees the host view's associated codebooks; a later decode makes a sub-volume's again. Only
  // while no host view of this layout is decoding.
  void releaseAssociated() const;
  // The view over joinedBytes() at `base`, or the host view when null, adding the first
  // `partitions` partitions to the mean (the progressive level; 3: all).
  kernels::TvqView view(const std::byte* base = nullptr, int partitions = 3) const;
  // Block (bx, by, bz)'s 64 coefficients as the file states them (the slow path: dequantized
  // codevectors, the mean as coefficient 0), and whether the block has a record.
  bool coefficients(int bx, int by, int bz, float* c) const;
  // Both decode every block with codebooks of their own, freed when they return.
  RangeGrid rangeGrid(int partitions = 3) const;
  Volume decode(int partitions = 3) const;

 private:
  struct Sub {
    std::array<int, 3> bits{};
    std::uint32_t background = 0;
    std::uint64_t coded = 0, firstRecordByte = 0, firstWord = 0;
    std::array<float, 3> scale{};
    std::array<std::vector<std::uint32_t>, 3> chapters;
    std::array<std::uint64_t, 3> codebookAt{};  // into section 4, in i16 values
  };
  class Books;  // associated codebooks made on first use
  // The constructor's steps: each section checked, then the table and ranks built from them.
  std::uint64_t readParams(const SectionSet& sections);  // returns the sub-volume count
  void readBasis(const SectionSet& sections);
  // Returns the occupancy words and record bytes the table needs.
  std::pair<std::uint64_t, std::uint64_t> readSubvolumes(const SectionSet& sections,
                                                         std::uint64_t subCount);
  void buildTable(const SectionSet& sections, std::uint64_t words, std::uint64_t recordBytes);
  // Sub-volume s's associated codebooks into `out` (zeroed, codebookAt[0] of the table there).
  void associateCodebooks(std::uint64_t s, float* out) const;
  std::uint64_t subBooksBytes(std::uint64_t s) const;  // sub-volume s's associated codebooks
  void rankOccupancy(std::uint64_t i, std::uint64_t local, const ByteReader& occupancy);
  void checkRecords(std::uint64_t i, const ByteReader& records) const;
  kernels::TvqView viewWith(const Books& books, int partitions) const;
  VolumeInfo info_;
  Transform transform_ = Transform::Klt;
  bool classified_ = true;
  int s_ = 64, dcBits_ = 8, codeBits_ = 0;
  double fidelity_ = 0, dcLo_ = 0, dcStep_ = 1;
  std::array<double, kProgressiveLevels> levelPsnr_{};
  std::array<std::uint64_t, 3> codevectors_{};
  std::uint64_t coded_ = 0;
  glm::ivec3 blocks_{}, grid_{};
  Basis basis_;
  std::vector<Sub> subvolumes_;
  std::vector<kernels::TvqSubvolume> table_;
  std::vector<std::uint32_t> ranks_;
  std::span<const std::byte> codebooks_, occupancy_, records_;
  std::uint64_t booksBytes_ = 0;
  std::unique_ptr<Books> books_;  // the host view's
  std::uint64_t cacheId_ = 0;
};

// The codec's registry entry (registry.hpp).
struct TvqCodecEntry {
  static constexpr CodecId kId{5};  // stored in files: never reused
  static constexpr std::string_view kName = "tvq";
  using Views = ViewList<kernels::TvqView>;
  static const Codec& instance();
};

}  // namespace voxwall::codec::tvq
