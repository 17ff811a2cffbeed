// The zfp codec's encoder: the mode's parameters (for a size target, the tolerance found on a
// sample of bricks), then each row of bricks (16 slices) read, compressed on every core, decoded
// back to measure, and appended. A brick zfp would enlarge is stored as it is.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/parallel.hpp>
#include <voxwall/core/text.hpp>

#include "format.hpp"

namespace voxwall::codec::zfp {
namespace {

// The bricks the size target is searched on: at most this many, spread over the volume.
constexpr std::uint64_t kSampleBricks = 1024;

// One brick coded: its bits (a zfp stream or its voxels as they are).
struct CodedBrick {
  BrickBits bits;
  bool stored = false;
};

template <class T>
class Encoder {
 public:
  Encoder(const VolumeSource& source, const Params& params, Progress& progress)
      : source_(source), params_(params), progress_(progress), grid_(brickGrid(source.dims)) {
    bricks_ = std::uint64_t(grid_.x) * std::uint64_t(grid_.y) * std::uint64_t(grid_.z);
  }

  CompressedVolume run(EncodeStats* stats) {
    checkInput();
    chooseMode();
    encodeRows();
    CompressedVolume out;
    out.info = volumeInfo(source_.headerVolume(), ZfpCodecEntry::kId);
    out.sections.push_back({kParams, paramsSection()});
    out.sections.push_back({kIndex, indexSection()});
    const std::uint64_t streamBytes = stream_.size();
    out.sections.push_back({kStream, std::move(stream_)});
    if (stats) {
      stats->mode = mode_, stats->setting = setting_;
      stats->bricks = bricks_, stats->storedBricks = stored_;
      stats->streamBytes = streamBytes;
      stats->indexBytes = Index::bytes(rowBases_.size() - 1, bricks_, entryBits());
      stats->bitsPerVoxel =
          8.0 * double(out.payloadBytes()) / double(std::max<std::size_t>(1, source_.voxelCount()));
      stats->psnr = psnr_, stats->maxError = maxError_;
      stats->searchSteps = searchSteps_;
    }
    return out;
  }

 private:
  void checkInput() {
    if (!source_.finite)
      throw std::invalid_argument(
          "zfp needs finite values: this float volume holds NaN or "
          "infinities");
    const auto [lo, hi] = source_.dataRange();
    lo_ = lo, hi_ = hi;
    if (!std::isfinite(lo_) || !std::isfinite(hi_))
      throw std::invalid_argument("zfp needs finite values");
    range_ = hi_ > lo_ ? hi_ - lo_ : 1.0;
  }

  // The mode and its zfp parameters, from the options or, for a size target, by search.
  void chooseMode() {
    mode_ = params_.mode;
    switch (mode_) {
      case Mode::Accuracy:
        setting_ = params_.tolerance > 0 ? params_.tolerance : range_ / 64;
        break;
      case Mode::Precision:
        setting_ = params_.precision;
        break;
      case Mode::Rate:
        setting_ = params_.rate;
        break;
      case Mode::Reversible:
        setting_ = 0;
        break;
    }
    if (params_.targetBitsPerVoxel > 0) searchTarget(params_.targetBitsPerVoxel);
    zfp_ = streamParams(mode_, setting_);
  }

  // Fixed accuracy with the largest tolerance whose file fits the target (zfp's tolerances are
  // powers of two), or reversible when the lossless file fits.
  void searchTarget(double target) {
    loadSample();
    if (sampleBitsPerVoxel(streamParams(Mode::Reversible, 0)) <= target) {
      mode_ = Mode::Reversible, setting_ = 0;
      return;
    }
    mode_ = Mode::Accuracy;
    // The smallest file: zfp codes a block's bit planes down to the tolerance plus 8 planes of
    // headroom for its transform, so a tolerance 2^10 above the largest magnitude codes none.
    const double magnitude = std::max({std::abs(lo_), std::abs(hi_), 1e-30});
    int coarse = int(std::ceil(std::log2(magnitude))) + 10;
    const double smallest =
        sampleBitsPerVoxel(streamParams(Mode::Accuracy, std::ldexp(1.0, coarse)));
    if (smallest > target)
      throw std::invalid_argument(formatLine(
          "--bits-per-voxel %g is below the smallest zfp file of this volume, about "
          "%.3g bits per voxel (its index alone is %.3g); ask for more, or use --rate",
          target, smallest, sampleIndexBits_ * double(bricks_) / double(source_.voxelCount())));
    int fine = coarse - 60;  // coarse fits, fine (2^-50 of the largest magnitude) need not
    while (coarse - fine > 1) {
      const int mid = (coarse + fine) / 2;
      if (sampleBitsPerVoxel(streamParams(Mode::Accuracy, std::ldexp(1.0, mid))) <= target)
        coarse = mid;
      else
        fine = mid;
    }
    setting_ = std::ldexp(1.0, coarse);
  }

  // Up to kSampleBricks bricks, every k-th in brick order, read a row at a time.
  void loadSample() {
    const std::uint64_t stride =
        std::max<std::uint64_t>(1, (bricks_ + kSampleBricks - 1) / kSampleBricks);
    const std::uint64_t perRow = std::uint64_t(grid_.x) * std::uint64_t(grid_.y);
    progress_.begin("sampling bricks", std::uint64_t(grid_.z));
    std::vector<T> row;
    for (int bz = 0; bz < grid_.z; ++bz) {
      const std::uint64_t first = std::uint64_t(bz) * perRow, end = first + perRow;
      const std::uint64_t from = (first + stride - 1) / stride * stride;
      if (from < end) {
        readRow(bz, row);
        for (std::uint64_t i = from; i < end; i += stride) {
          const BrickShape s = brickShape(source_.dims, i);
          sample_.emplace_back(kBrickVoxels);
          gather(row, i - first, s, sample_.back().data());
          sampleShapes_.push_back(s);
          sampleVoxels_ += std::uint64_t(s.voxels());
        }
      }
      progress_.advance();
    }
    progress_.end();
  }

  double sampleBitsPerVoxel(const kernels::ZfpStreamParams& p) {
    ++searchSteps_;
    std::vector<std::uint64_t> bits(sample_.size());
    parallelFor(sample_.size(), params_.threads, [&](std::size_t i) {
      bits[i] = std::min(compressBrick(p, sample_[i].data(), sampleShapes_[i]).bits,
                         storedBits(source_.type, sampleShapes_[i]));
    });
    double total = 0;
    std::uint64_t largest = 0;
    for (std::uint64_t b : bits) total += double(b), largest = std::max(largest, b);
    // A brick's share of the index: its entry, as wide as a row of the sample's largest bricks
    // needs, and its row's start.
    sampleIndexBits_ =
        double(Index::bitsFor(std::min(largest * std::uint64_t(grid_.x - 1), kMaxRowBits))) +
        64.0 / double(grid_.x);
    total += sampleIndexBits_ * double(bits.size());
    return total / double(std::max<std::uint64_t>(1, sampleVoxels_));
  }

  void readRow(int bz, std::vector<T>& row) const {
    row.resize(std::size_t(kBrick) * source_.sliceVoxels());
    source_.readSlices(bz * kBrick, kBrick, std::as_writable_bytes(std::span(row)));
  }

  // Brick `inRow` (bx + by bricksX) of a row into brick[x + 16 (y + 16 z)] as floats.
  void gather(const std::vector<T>& row, std::uint64_t inRow, const BrickShape& s,
              float* brick) const {
    const int bx = int(inRow % std::uint64_t(grid_.x)), by = int(inRow / std::uint64_t(grid_.x));
    const std::size_t dx = std::size_t(source_.dims.x), slice = source_.sliceVoxels();
    for (int z = 0; z < s.nz; ++z)
      for (int y = 0; y < s.ny; ++y) {
        const T* in = row.data() + std::size_t(z) * slice + std::size_t(by * kBrick + y) * dx +
                      std::size_t(bx * kBrick);
        float* out = brick + kBrick * (y + kBrick * z);
        for (int x = 0; x < s.nx; ++x) out[x] = float(in[x]);
      }
  }

  // Codes one brick and writes what a reader decodes from it into decoded[x + 16 (y + 16 z)].
  CodedBrick codeBrick(const float* voxels, const BrickShape& s, float* decoded) const {
    CodedBrick b;
    b.bits = compressBrick(zfp_, voxels, s);
    if (b.bits.bits >= storedBits(source_.type, s)) {
      b.stored = true;
      b.bits = storeBrick(source_.type, voxels, s);
      std::copy(voxels, voxels + kBrickVoxels, decoded);
      return b;
    }
    decodeBrick(zfp_, source_.type, false,
                reinterpret_cast<const std::uint8_t*>(b.bits.words.data()), 0, b.bits.bits, s,
                decoded);
    finishBrick(decoded, s, float(lo_), float(hi_), std::is_integral_v<T>);
    return b;
  }

  void encodeRows() {
    const std::uint64_t perRow = std::uint64_t(grid_.x) * std::uint64_t(grid_.y);
    PsnrSum psnr(source_.headerVolume());
    std::vector<T> row, decodedRow;
    std::vector<CodedBrick> coded(perRow);
    std::vector<double> rowError(perRow);
    entries_.reserve(bricks_);
    // At most the voxels' own bits (a brick zfp would make larger is stored): reserved, the stream
    // never moves, and only what it holds becomes resident.
    stream_.reserve((source_.voxelCount() * scalarBytes(source_.type) + 7) / 8 * 8 + 8);
    progress_.begin("zfp bricks", bricks_);
    for (int bz = 0; bz < grid_.z; ++bz) {
      readRow(bz, row);
      decodedRow.assign(row.size(), T{});
      parallelFor(perRow, params_.threads, [&](std::size_t i) {
        const BrickShape s = brickShape(source_.dims, std::uint64_t(bz) * perRow + i);
        std::vector<float> voxels(kBrickVoxels), decoded(kBrickVoxels);
        gather(row, i, s, voxels.data());
        coded[i] = codeBrick(voxels.data(), s, decoded.data());
        rowError[i] = scatter(decoded.data(), voxels.data(), i, s, decodedRow);
        progress_.advance();
      });
      for (std::size_t i = 0; i < perRow; ++i) {
        if (i % std::size_t(grid_.x) == 0) rowBases_.push_back(streamBits_);
        const std::uint64_t offset = streamBits_ - rowBases_.back();
        if (offset > kMaxRowBits)
          throw std::invalid_argument(
              "a row of zfp bricks along x is over 2^31 bits: the volume "
              "is too wide for the zfp codec's index");
        entries_.push_back(std::uint32_t(offset) | (coded[i].stored ? kStoredFlag : 0));
        stored_ += coded[i].stored ? 1 : 0;
        appendBits(stream_, streamBits_, coded[i].bits);
        maxError_ = std::max(maxError_, rowError[i]);
      }
      const int slices = std::min(kBrick, source_.dims.z - bz * kBrick);
      psnr.add(row.data(), decodedRow.data(), std::size_t(slices) * source_.sliceVoxels());
    }
    rowBases_.push_back(streamBits_);
    progress_.end();
    psnr_ = psnr.psnr();
  }

  // Writes a decoded brick into the decoded row (in T) and returns its largest error.
  double scatter(const float* decoded, const float* voxels, std::uint64_t inRow,
                 const BrickShape& s, std::vector<T>& decodedRow) const {
    const int bx = int(inRow % std::uint64_t(grid_.x)), by = int(inRow / std::uint64_t(grid_.x));
    const std::size_t dx = std::size_t(source_.dims.x), slice = source_.sliceVoxels();
    double error = 0;
    for (int z = 0; z < s.nz; ++z)
      for (int y = 0; y < s.ny; ++y) {
        T* out = decodedRow.data() + std::size_t(z) * slice + std::size_t(by * kBrick + y) * dx +
                 std::size_t(bx * kBrick);
        const int at = kBrick * (y + kBrick * z);
        for (int x = 0; x < s.nx; ++x) {
          out[x] = T(decoded[at + x]);
          error = std::max(error, std::abs(double(decoded[at + x]) - double(voxels[at + x])));
        }
      }
    return error;
  }

  std::vector<std::byte> paramsSection() const {
    std::vector<std::byte> out;
    ByteWriter w(out);
    w.put(std::uint32_t(mode_));
    w.put(zfp_.minbits), w.put(zfp_.maxbits), w.put(zfp_.maxprec), w.put(zfp_.minexp);
    w.put(std::uint32_t(entryBits()));
    w.put(setting_), w.put(psnr_), w.put(maxError_);
    w.put(stored_);
    w.put(lo_), w.put(hi_);
    return out;
  }

  // The narrowest entry that holds every brick's offset in its row, and the stored flag.
  int entryBits() const {
    std::uint32_t largest = 0;
    for (std::uint32_t e : entries_) largest = std::max(largest, e & ~kStoredFlag);
    return Index::bitsFor(largest);
  }

  // The row starts, then the entries packed LSB first at entryBits() bits each.
  std::vector<std::byte> indexSection() const {
    std::vector<std::byte> out;
    ByteWriter w(out);
    for (std::uint64_t base : rowBases_) w.put(base);
    const int bits = entryBits();
    const std::size_t at = out.size();
    out.resize(Index::bytes(rowBases_.size() - 1, entries_.size(), bits), std::byte{0});
    const std::uint64_t flagAt = std::uint64_t(1) << (bits - 1);
    for (std::size_t i = 0; i < entries_.size(); ++i) {
      const std::uint64_t e =
          (entries_[i] & ~kStoredFlag) | (entries_[i] & kStoredFlag ? flagAt : 0);
      const std::uint64_t bit = std::uint64_t(i) * std::uint64_t(bits);
      for (int b = 0; b < bits; ++b)
        if ((e >> b) & 1)
          out[at + (bit + std::uint64_t(b)) / 8] |= std::byte(1u << ((bit + std::uint64_t(b)) % 8));
    }
    return out;
  }

  const VolumeSource& source_;
  const Params params_;
  Progress& progress_;
  glm::ivec3 grid_;
  std::uint64_t bricks_ = 0;
  double lo_ = 0, hi_ = 0, range_ = 1;
  Mode mode_ = Mode::Accuracy;
  double setting_ = 0;
  kernels::ZfpStreamParams zfp_;
  std::vector<std::vector<float>> sample_;
  std::vector<BrickShape> sampleShapes_;
  std::uint64_t sampleVoxels_ = 0;
  int searchSteps_ = 0;
  double sampleIndexBits_ = 32;  // a brick's share of the index, at the last sampled setting
  std::vector<std::byte> stream_;
  std::vector<std::uint64_t> rowBases_;
  std::uint64_t streamBits_ = 0;
  std::vector<std::uint32_t> entries_;
  std::uint64_t stored_ = 0;
  double psnr_ = 0, maxError_ = 0;
};

void checkParams(const Params& p) {
  if (p.mode == Mode::Accuracy && !(p.tolerance >= 0 && std::isfinite(p.tolerance)))
    throw std::invalid_argument("--tolerance must be a finite number > 0");
  if (p.mode == Mode::Precision && (p.precision < 1 || p.precision > 32))
    throw std::invalid_argument("--precision must be 1..32 bit planes");
  if (p.mode == Mode::Rate && !(p.rate >= 0.25 && p.rate <= 32))
    throw std::invalid_argument("--rate must be 0.25..32 bits per voxel");
  if (p.targetBitsPerVoxel < 0 || !std::isfinite(p.targetBitsPerVoxel))
    throw std::invalid_argument("--bits-per-voxel must be a finite number > 0");
}

}  // namespace

CompressedVolume encode(const VolumeSource& source, const Params& params, Progress& progress,
                        EncodeStats* stats) {
  checkParams(params);
  return dispatchScalar(source.type, [&](auto t) {
    return Encoder<decltype(t)>(source, params, progress).run(stats);
  });
}

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats) {
  return encode(*memorySource(volume), params, progress, stats);
}

}  // namespace voxwall::codec::zfp
