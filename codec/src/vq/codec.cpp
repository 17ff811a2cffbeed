// The vq codec; the byte layout is documented in vq_codec.hpp.
#include <xxhash.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/codec/vq_kmeans.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>

#include "book.hpp"

namespace voxwall::codec::vq {

namespace {

constexpr std::size_t kPad = 8;  // zero bytes after every array (8-byte reads)

// Writes `count` entries of `bits` bits, value(i) each, into a zero-initialised buffer at byte
// offset `at`.
template <class Value>
void packInto(std::vector<std::byte>& buf, std::size_t at, std::size_t count, int bits,
              Value value) {
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint64_t v = value(i);
    const std::uint64_t bit = std::uint64_t(i) * std::uint64_t(bits);
    for (int b = 0; b < bits; ++b)
      if ((v >> b) & 1u) {
        const std::uint64_t pos = bit + std::uint64_t(b);
        buf[at + (pos >> 3)] |= std::byte(1u << (pos & 7));
      }
  }
}

std::size_t packedBytes(std::uint64_t count, int bits) {
  return std::size_t((count * std::uint64_t(bits) + 7) / 8);
}
std::size_t align64(std::size_t n) { return (n + 63) / 64 * 64; }

struct BrickHash {
  std::size_t operator()(const Brick& b) const {
    return std::size_t(XXH3_64bits(b.data(), sizeof(Brick)));
  }
};

// Estimated bytes of a compressed codeword, from a sample of the bricks.
double meanCodewordBytes(const UniqueBricks& bricks, int bits) {
  const std::size_t step = std::max<std::size_t>(1, bricks.size() / 4096);
  double sum = 0;
  std::size_t n = 0;
  std::vector<std::uint8_t> scratch;
  for (std::size_t i = 0; i < bricks.size(); i += step, ++n) {
    scratch.clear();
    encodeCodeword(bricks[i], bits, scratch);
    sum += double(scratch.size());
  }
  return n ? sum / double(n) : 0.0;
}

}  // namespace

namespace {

// The unique bricks of a volume in order of first appearance (a row of bricks at a time, in
// brick order, so the same whatever the threads), each brick's index among them and how many
// bricks each stands for.
struct Uniques {
  explicit Uniques(int bits) : bricks(bits) {}
  UniqueBricks bricks;
  std::vector<std::uint32_t> brickToUnique, weight;
};
Uniques findUniqueBricks(const VolumeSource& volume, int bits, int bias, int threads,
                         Progress& progress) {
  const glm::ivec3 bricks = (volume.dims + 3) / 4;
  const std::size_t rowBricks = std::size_t(bricks.x) * std::size_t(bricks.y);
  Uniques u(bits);
  u.brickToUnique.resize(rowBricks * std::size_t(bricks.z));
  std::vector<Brick> row;
  std::vector<std::byte> window;
  progress.begin("bricking", u.brickToUnique.size());
  for (int bz = 0; bz < bricks.z; ++bz) {
    gatherRow(volume, bz, bias, threads, window, row);
    for (std::size_t j = 0; j < rowBricks; ++j) {
      bool added = false;
      const std::uint32_t i = u.bricks.insert(row[j], added);
      if (added) u.weight.push_back(0);
      u.brickToUnique[std::size_t(bz) * rowBricks + j] = i;
      ++u.weight[i];
    }
    progress.advance(rowBricks);
  }
  progress.end();
  u.bricks.seal();
  return u;
}

// Codes codewords 0 .. m-1 (codeword(i): a Brick), a chunk of 1024 per task into one buffer each
// (a buffer per codeword would cost more than the codewords), joined in order; `done()` is
// called once every codeword is coded, before the join (the caller frees its bricks).
template <class Codeword, class Done>
CodedBook codeBook(std::size_t m, const Codeword& codeword, int bits, bool compressed, int threads,
                   Progress& progress, EncodeStats& stats, const Done& done) {
  CodedBook book;
  book.address.resize(m);
  progress.begin("coding codebook", m);
  const std::size_t chunks = (m + 1023) / 1024;
  std::vector<std::vector<std::uint8_t>> coded(chunks);
  std::vector<std::uint8_t> length(m);  // a codeword is at most maxCodewordBytes(16) = 133
  std::vector<std::int16_t> used(m, -1);
  parallelFor(chunks, threads, [&](std::size_t chunk) {
    const std::size_t end = std::min<std::size_t>(m, (chunk + 1) * 1024);
    for (std::size_t i = chunk * 1024; i < end; ++i) {
      const std::size_t before = coded[chunk].size();
      if (compressed)
        used[i] = std::int16_t(encodeCodeword(codeword(i), bits, coded[chunk]));
      else
        plainCodeword(codeword(i), bits, coded[chunk]);
      length[i] = std::uint8_t(coded[chunk].size() - before);
    }
    progress.advance(end - chunk * 1024);
  });
  done();
  for (std::size_t chunk = 0; chunk < chunks; ++chunk) {
    std::uint64_t at = book.bytes.size();
    for (std::size_t i = chunk * 1024; i < std::min<std::size_t>(m, (chunk + 1) * 1024); ++i) {
      book.address[i] = at, at += length[i];
      if (used[i] == kernels::kVqEscape)
        ++stats.escapes;
      else if (used[i] >= 0)
        ++stats.transformUse[used[i]];
    }
    book.bytes.append(coded[chunk].data(), coded[chunk].size());
    std::vector<std::uint8_t>().swap(coded[chunk]);
  }
  progress.end();
  return book;
}

// The codebook of a reduced file (--reduction, or --bits-per-voxel, which may also find the
// lossless codebook small enough): the unique bricks, reduced by k-means (section 4), coded.
CodedBook reducedBook(const VolumeSource& volume, int bits, int bias, const Params& params,
                      Progress& progress, EncodeStats& stats, int& reduction) {
  const glm::ivec3 bricks = (volume.dims + 3) / 4;
  const std::size_t brickCount =
      std::size_t(bricks.x) * std::size_t(bricks.y) * std::size_t(bricks.z);
  Uniques u = findUniqueBricks(volume, bits, bias, params.threads, progress);
  UniqueBricks& unique = u.bricks;
  const std::size_t uniqueCount = unique.size();
  stats.uniqueBricks = uniqueCount;
  // ---- data reduction (section 4) ----
  // The codebook: the unique bricks themselves (lossless) or the rounded k-means centres.
  std::vector<Brick> codebook;
  bool uniqueCodebook = false;
  std::vector<std::uint32_t> brickToCodeword;  // sized by reduce(), or the unique map moved in
  const std::uint64_t maxValue = (std::uint64_t(1) << bits) - 1;
  std::vector<Point> points;  // the unique bricks as k-means points, made on the first reduce
  auto reduce = [&](std::size_t k) {
    if (points.empty()) {
      points = unique.all();
      unique.clear();  // k-means codes from its centres from here on
    }
    const auto start = std::chrono::steady_clock::now();
    const KMeansResult r =
        kmeans(points, u.weight, k, params.maxIterations, params.threads, progress);
    stats.kmeansSeconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    stats.iterations = r.iterations;
    stats.distancesComputed = r.computed, stats.distancesSkipped = r.skipped;
    stats.plainEquivalent = r.plainEquivalent;
    // Round the centres; drop clusters nobody uses and centres that round to the same brick.
    std::vector<char> used(r.centers.size(), 0);
    for (const auto a : r.assignment) used[a] = 1;
    std::unordered_map<Brick, std::uint32_t, BrickHash> index;
    std::vector<std::uint32_t> centerToCodeword(r.centers.size(), 0);
    codebook.clear();
    for (std::size_t c = 0; c < r.centers.size(); ++c) {
      if (!used[c]) continue;
      Brick b;
      for (int d = 0; d < kN; ++d)
        b[d] = std::uint16_t(std::clamp(std::llround(r.centers[c][d]), 0ll, (long long)maxValue));
      const auto [it, inserted] = index.try_emplace(b, std::uint32_t(codebook.size()));
      if (inserted) codebook.push_back(b);
      centerToCodeword[c] = it->second;
    }
    brickToCodeword.resize(brickCount);
    for (std::size_t i = 0; i < brickCount; ++i)
      brickToCodeword[i] = centerToCodeword[r.assignment[u.brickToUnique[i]]];
  };
  auto keepLossless = [&] {
    codebook.clear();
    uniqueCodebook = true;
    brickToCodeword = std::move(u.brickToUnique);
    std::vector<std::uint32_t>().swap(u.weight);  // only k-means weighs the bricks
  };
  if (params.targetBitsPerVoxel > 0) {
    // Choose k from a size model (offset volume + mean codeword size), run k-means, and shrink
    // k while the result is still above the target.
    const double perCodeword =
        params.compressedCodebook ? meanCodewordBytes(unique, bits) : double(8 * bits);
    const double voxels = double(volume.voxelCount());
    auto model = [&](double k) {
      return (double(brickCount) * bitsFor(std::uint64_t(std::max(1.0, k) - 1)) +
              8.0 * k * perCodeword) /
             voxels;
    };
    if (model(double(uniqueCount)) <= params.targetBitsPerVoxel) {
      keepLossless();
      reduction = 1;
    } else {
      double k = double(uniqueCount);
      while (k > 1 && model(k) > params.targetBitsPerVoxel) k = std::floor(k * 0.9);
      for (int attempt = 0; attempt < 6; ++attempt) {
        reduce(std::size_t(std::max(1.0, k)));
        std::uint64_t bytes = packedBytes(brickCount, bitsFor(codebook.size() - 1));
        std::vector<std::uint8_t> scratch;
        for (const auto& b : codebook)
          if (params.compressedCodebook)
            encodeCodeword(b, bits, scratch);
          else
            plainCodeword(b, bits, scratch);
        bytes += scratch.size();
        const double bpv = 8.0 * double(bytes) / voxels;
        if (bpv <= params.targetBitsPerVoxel * 1.02 || k <= 1) break;
        k = std::floor(k * std::min(0.95, params.targetBitsPerVoxel / bpv));
      }
      reduction = int(std::lround(double(uniqueCount) / double(codebook.size())));
    }
  } else if (params.reduction > 1) {
    reduce(std::max<std::size_t>(1, uniqueCount / std::size_t(params.reduction)));
  } else {
    keepLossless();
  }
  std::vector<Point>().swap(points);
  if (!uniqueCodebook) unique.clear();
  const std::size_t m = uniqueCodebook ? unique.size() : codebook.size();
  CodedBook book = codeBook(
      m, [&](std::size_t i) { return uniqueCodebook ? unique[i] : codebook[i]; }, bits,
      params.compressedCodebook, params.threads, progress, stats,
      [&] {
        // The bricks are coded: free them before joining.
        std::vector<Brick>().swap(codebook);
        unique.clear();
      });
  book.brickToCodeword = std::move(brickToCodeword);
  return book;
}

}  // namespace

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* statsOut) {
  return encode(*memorySource(volume), params, progress, statsOut);
}

CompressedVolume encode(const VolumeSource& volume, const Params& params, Progress& progress,
                        EncodeStats* statsOut) {
  const auto [lowest, highest] = volume.dataRange();
  const int bits = bitDepth(volume.type, lowest, highest);
  if (params.reduction < 1 || params.reduction > 1 << 20)
    throw std::invalid_argument("vq codec: --reduction must be 1 (lossless) to 1048576, not " +
                                std::to_string(params.reduction));
  if (params.targetBitsPerVoxel < 0 || !std::isfinite(params.targetBitsPerVoxel))
    throw std::invalid_argument("vq codec: --bits-per-voxel must be positive");
  const int bias = volume.type == ScalarType::Int16 ? int(lowest) : 0;
  const glm::ivec3 bricks = (volume.dims + 3) / 4;
  const std::size_t brickCount =
      std::size_t(bricks.x) * std::size_t(bricks.y) * std::size_t(bricks.z);
  EncodeStats stats;
  stats.bricks = brickCount;

  // ---- the codebook (sections 3 and 4) ----
  // A lossless file codes each row of bricks and deduplicates the codes: no brick is held beyond
  // its row (book.hpp). Reducing needs the bricks themselves (reducedBook).
  CodedBook book;
  int reduction = params.reduction;
  if (params.reduction == 1 && params.targetBitsPerVoxel == 0)
    book = losslessBook(volume, bits, bias, params.compressedCodebook, params.threads, progress,
                        stats);
  else
    book = reducedBook(volume, bits, bias, params, progress, stats, reduction);
  const std::uint64_t m = book.address.size();
  stats.codewords = m;
  stats.reduction = reduction;
  const std::uint64_t codebookBytes = book.bytes.size();

  const bool indirect = params.compressedCodebook && chooseIndirect(brickCount, m, codebookBytes);
  const int indexBits = bitsFor(m - 1);
  const int addressBits = bitsFor(codebookBytes == 0 ? 0 : codebookBytes - 1);
  const int offsetBits = params.compressedCodebook && !indirect ? addressBits : indexBits;
  const std::size_t offsetBytes = packedBytes(brickCount, offsetBits);
  const std::size_t tableBytes = indirect ? packedBytes(m, addressBits) : 0;
  const std::size_t indexTableAt = align64(offsetBytes + kPad);
  const std::size_t codebookAt =
      indirect ? align64(indexTableAt + tableBytes + kPad) : indexTableAt;
  std::vector<std::byte> data(align64(codebookAt + std::size_t(codebookBytes) + kPad),
                              std::byte{0});
  const bool byAddress = params.compressedCodebook && !indirect;
  packInto(data, 0, brickCount, offsetBits, [&](std::size_t i) -> std::uint64_t {
    return byAddress ? book.address[book.brickToCodeword[i]] : book.brickToCodeword[i];
  });
  if (indirect)
    packInto(data, indexTableAt, book.address.size(), addressBits,
             [&](std::size_t i) { return book.address[i]; });
  book.bytes.copyTo(data.data() + codebookAt);
  book = {};
  stats.indirect = indirect;
  stats.offsetVolumeBytes = offsetBytes, stats.indexTableBytes = tableBytes;
  stats.codebookBytes = codebookBytes;

  CompressedVolume out;
  out.info = volumeInfo(volume.headerVolume(), VqCodecEntry::kId);
  auto writeParams = [&](double psnr) {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    w.put<std::uint32_t>(std::uint32_t(bits));
    w.put<std::int32_t>(bias);
    w.put<std::uint32_t>((params.compressedCodebook ? kCompressed : 0u) |
                         (indirect ? kIndirect : 0u));
    w.put<std::uint32_t>(std::uint32_t(offsetBits));
    w.put<std::uint32_t>(indirect ? std::uint32_t(addressBits) : 0u);
    w.put<std::uint32_t>(std::uint32_t(reduction));
    w.put<std::uint64_t>(m);
    w.put<std::uint64_t>(indexTableAt);
    w.put<std::uint64_t>(codebookAt);
    w.put<std::uint64_t>(codebookBytes);
    w.put<double>(psnr);
    return bytes;
  };
  const bool lossless = m == stats.uniqueBricks && reduction == 1;
  out.sections.emplace_back(kParams, writeParams(std::numeric_limits<double>::infinity()));
  out.sections.emplace_back(kData, std::move(data));
  // The quality of what was stored, measured on the decoder's output.
  stats.psnr = std::numeric_limits<double>::infinity();
  if (!lossless) {
    progress.begin("measuring PSNR", 1);
    stats.psnr = brickPsnr(volume, Layout(out.info, out.view()).view());
    progress.advance();
    progress.end();
    out.sections[0].second = writeParams(stats.psnr);
  }
  if (statsOut) *statsOut = stats;
  return out;
}

// ---- a series with one codebook -----------------------------------------------------------

namespace {

// The steps of a series one above the other along z, each padded to whole bricks by repeating
// its last slice, so that its bricks are the ones it has alone. Steps are opened as the encoder
// reaches them (one at a time: it reads in z order); each was opened once first for its header
// and value range.
class StackedSteps final : public VolumeSource {
 public:
  StackedSteps(const SeriesSource& series, Progress& progress) : series_(series) {
    for (int k = 0; k < series.steps(); ++k) {
      const auto step = series.open(k, progress);
      headers_.push_back(step->headerVolume());
      finite = finite && step->finite;
      if (k == 0) {
        dims = step->dims, spacing = step->spacing, orientation = step->orientation;
        type = step->type, valueMin = step->valueMin, valueMax = step->valueMax;
      }
      valueMin = std::min(valueMin, step->valueMin);
      valueMax = std::max(valueMax, step->valueMax);
    }
    stepDepth_ = (dims.z + 3) / 4 * 4;
    dims.z = stepDepth_ * series.steps();
  }
  bool streams() const override { return true; }
  const Volume* inMemory() const override { return nullptr; }
  int stepDepth() const { return stepDepth_; }
  // Step k's header: its size, type, geometry and value range, no data.
  const Volume& header(int k) const { return headers_.at(std::size_t(k)); }

 protected:
  void read(int z0, int count, std::byte* out) const override {
    std::lock_guard lock(mutex_);
    const int depth = header(0).dims.z;
    while (count > 0) {
      const int k = z0 / stepDepth_, local = z0 % stepDepth_;
      const int run = std::min(count, stepDepth_ - local);
      if (!open_ || openStep_ != k) {
        open_.reset();
        // Quietly: the encoder's own progress is under way (the ranges were read, and said, when
        // the steps were first opened).
        voxwall::Progress quiet;
        open_ = series_.open(k, quiet);
        openStep_ = k;
      }
      // Slices past the step's last repeat it (readSlices does, from a slice inside it).
      const int first = std::min(local, depth - 1);
      const std::size_t bytes = sliceBytes();
      if (local < depth) {
        open_->readSlices(first, run, std::span(out, std::size_t(run) * bytes));
      } else {
        open_->readSlices(depth - 1, 1, std::span(out, bytes));
        for (int i = 1; i < run; ++i) std::copy_n(out, bytes, out + std::size_t(i) * bytes);
      }
      out += std::size_t(run) * bytes;
      z0 += run, count -= run;
    }
  }

 private:
  const SeriesSource& series_;
  std::vector<Volume> headers_;
  int stepDepth_ = 4;
  mutable std::mutex mutex_;
  mutable std::unique_ptr<VolumeSource> open_;
  mutable int openStep_ = -1;
};

// Fields of the params section (the layout in vq_codec.hpp).
constexpr std::size_t kFlagsAt = 8, kIndexTableAt = 32, kCodebookAt = 40, kPsnrAt = 56;

template <class T>
T fieldOf(const std::vector<std::byte>& params, std::size_t at) {
  T v;
  std::memcpy(&v, params.data() + at, sizeof v);
  return v;
}
template <class T>
void setField(std::vector<std::byte>& params, std::size_t at, T v) {
  std::memcpy(params.data() + at, &v, sizeof v);
}

}  // namespace

CompressedSeries encodeSeries(const SeriesSource& series, const Params& params, Progress& progress,
                              std::vector<EncodeStats>* statsOut) {
  const int steps = series.steps();
  progress.setPrefix("reading the steps' ranges: ");
  const StackedSteps stacked(series, progress);
  progress.setPrefix("");
  EncodeStats whole;
  CompressedVolume tall = encode(stacked, params, progress, &whole);
  const Layout tallLayout(tall.info, tall.view());  // validates what is cut below
  const std::vector<std::byte>& tallParams = tall.sections[0].second;
  const std::vector<std::byte>& tallData = tall.sections[1].second;
  const auto indexTableAt = fieldOf<std::uint64_t>(tallParams, kIndexTableAt);
  const auto codebookAt = fieldOf<std::uint64_t>(tallParams, kCodebookAt);
  const int offsetBits = int(fieldOf<std::uint32_t>(tallParams, 12));

  // The shared book: the index table and codebook, which start at indexTableAt (64-aligned).
  std::vector<std::byte> book(tallData.begin() + std::ptrdiff_t(indexTableAt), tallData.end());
  const glm::ivec3 d = stacked.header(0).dims;
  const glm::ivec3 b = (d + 3) / 4;
  const std::uint64_t perStep = std::uint64_t(b.x) * std::uint64_t(b.y) * std::uint64_t(b.z);
  const auto* tallBase = reinterpret_cast<const std::uint8_t*>(tallData.data());

  std::vector<CompressedVolume> coded;
  std::vector<EncodeStats> stats;
  const bool lossless = std::isinf(whole.psnr);
  progress.begin("cutting the series into steps", std::uint64_t(steps));
  for (int k = 0; k < steps; ++k) {
    CompressedVolume step;
    step.info = volumeInfo(stacked.header(k), VqCodecEntry::kId);
    std::vector<std::byte> data(align64(packedBytes(perStep, offsetBits) + kPad), std::byte{0});
    packInto(data, 0, std::size_t(perStep), offsetBits, [&](std::size_t i) {
      return kernels::readBits(
          tallBase, (std::uint64_t(k) * perStep + i) * std::uint64_t(offsetBits), offsetBits);
    });
    std::vector<std::byte> p = tallParams;
    setField(p, kFlagsAt, fieldOf<std::uint32_t>(p, kFlagsAt) | std::uint32_t(kSharedBook));
    setField(p, kIndexTableAt, std::uint64_t(0));
    setField(p, kCodebookAt, codebookAt - indexTableAt);
    EncodeStats s = whole;
    s.bricks = perStep;
    s.offsetVolumeBytes = packedBytes(perStep, offsetBits);
    s.psnr = std::numeric_limits<double>::infinity();
    if (!lossless) {
      // This step's quality, on the decoder's output against the step itself.
      SectionSet view{"<memory>", {{kParams, p}, {kData, data}, {kBook, book}}};
      VolumeInfo info = step.info;
      info.steps = steps;
      voxwall::Progress quiet;  // inside this loop's progress
      const auto source = series.open(k, quiet);
      s.psnr = brickPsnr(*source, Layout(info, view).view());
    }
    setField(p, kPsnrAt, s.psnr);
    step.sections.emplace_back(kParams, std::move(p));
    step.sections.emplace_back(kData, std::move(data));
    coded.push_back(std::move(step));
    stats.push_back(s);
    progress.advance();
  }
  progress.end();
  tall = {};
  CompressedSeries out = makeSeries(std::move(coded));
  out.shared.emplace_back(kBook, std::move(book));
  if (statsOut) *statsOut = std::move(stats);
  return out;
}

// ---- reading ------------------------------------------------------------------------------

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  cacheId_ = mintCacheIds();
  const std::string& src = sections.source;
  ByteReader r(sections.get(kParams, "params"), src, "section 'params'");
  bits_ = int(r.get<std::uint32_t>());
  bias_ = r.get<std::int32_t>();
  flags_ = r.get<std::uint32_t>();
  offsetBits_ = int(r.get<std::uint32_t>());
  addressBits_ = int(r.get<std::uint32_t>());
  reduction_ = int(r.get<std::uint32_t>());
  codewords_ = r.get<std::uint64_t>();
  indexTableAt_ = r.get<std::uint64_t>();
  codebookAt_ = r.get<std::uint64_t>();
  codebookBytes_ = r.get<std::uint64_t>();
  psnr_ = r.get<double>();
  auto fail = [&](const std::string& what) { r.fail(what); };
  if (bits_ != 8 && bits_ != 12 && bits_ != 16)
    fail("bit depth " + std::to_string(bits_) + " (8, 12 or 16)");
  if (info.type == ScalarType::Float32) fail("float32 volumes cannot be vq-coded");
  if (info.type == ScalarType::UInt8 && bits_ != 8) fail("uint8 data must be 8-bit");
  if (info.type != ScalarType::UInt8 && bits_ == 8) fail("16-bit types are coded at 12 or 16 bits");
  if (info.type != ScalarType::Int16 && bias_ != 0) fail("bias on unsigned data");
  if (bias_ < -32768 || bias_ > 32767) fail("bias out of range");
  if (flags_ > 7 || (flags_ & 3) == kIndirect) fail("flags " + std::to_string(flags_));
  const bool compressed = flags_ & kCompressed, indirect = flags_ & kIndirect;
  const bool shared = flags_ & kSharedBook;
  if (offsetBits_ < 1 || offsetBits_ > 57) fail("offset bits " + std::to_string(offsetBits_));
  if (indirect ? (addressBits_ < 1 || addressBits_ > 57) : addressBits_ != 0)
    fail("address bits " + std::to_string(addressBits_));
  if (reduction_ < 1) fail("reduction 0");
  const glm::ivec3 bricks = (info.dims + 3) / 4;
  const std::uint64_t n =
      std::uint64_t(bricks.x) * std::uint64_t(bricks.y) * std::uint64_t(bricks.z);
  // A shared book holds the codewords of every step of a series (counted by the walk below).
  const std::uint64_t maxCodewords = shared ? std::uint64_t(1) << 32 : n;
  if (codewords_ < 1 || codewords_ > maxCodewords)
    fail(std::to_string(codewords_) + " codewords for " + std::to_string(maxCodewords) + " bricks");
  data_ = sections.get(kData, "data");
  book_ = shared ? sections.get(kBook, "book") : data_;
  ByteReader br(book_, src, shared ? "section 'book'" : "section 'data'");
  auto dfail = [&](const std::string& what) { br.fail(what); };
  const std::uint64_t size = book_.size();
  const std::uint64_t offsetBytes = (n * std::uint64_t(offsetBits_) + 7) / 8;
  const std::uint64_t tableEnd =
      indirect ? indexTableAt_ + (codewords_ * std::uint64_t(addressBits_) + 7) / 8 : 0;
  if (indexTableAt_ > size || codebookAt_ > size)
    dfail("array offsets past the section's " + std::to_string(size) + " bytes");
  if (indexTableAt_ % 64 || codebookAt_ % 64) dfail("arrays not aligned to 64 bytes");
  if (shared ? offsetBytes + kPad > data_.size() : offsetBytes + kPad > indexTableAt_)
    ByteReader(data_, src, "section 'data'").fail("offset volume overlaps the next array");
  if (indirect ? tableEnd + kPad > codebookAt_ : codebookAt_ != indexTableAt_)
    dfail("index table does not fit");
  if (codebookAt_ > size || codebookBytes_ > size - codebookAt_ ||
      size - codebookAt_ - codebookBytes_ < kPad)
    dfail("codebook of " + std::to_string(codebookBytes_) + " bytes does not fit in " +
          std::to_string(size) + " bytes");
  if (!compressed && codebookBytes_ != codewords_ * std::uint64_t(8 * bits_))
    dfail("plain codebook size does not match its codewords");
  const auto* base = reinterpret_cast<const std::uint8_t*>(data_.data());
  const auto* book = reinterpret_cast<const std::uint8_t*>(book_.data());

  // Walk the codebook: every codeword well-formed, the count right, the index table (indirect)
  // naming each one's start. A codeword has its minimum and maximum at least, which bounds the
  // count. The starts are marked in a bitmap of the codebook's bytes, so that checking an offset
  // entry (direct) is one bit (a binary search in a list of the starts, for every brick of the
  // 452x555x474 MRI, was a tenth of a job of one small frame).
  std::vector<std::uint64_t> startBits;
  if (compressed) {
    const std::uint64_t fewestBytes = std::uint64_t(2 * bits_ + 7) / 8;
    if (codewords_ > codebookBytes_ / fewestBytes)
      dfail("more codewords than the codebook's " + std::to_string(codebookBytes_) +
            " bytes can hold (the header says " + std::to_string(codewords_) + ")");
    if (!indirect) startBits.assign((codebookBytes_ + 63) / 64, 0);
    std::uint64_t pos = 0, count = 0;
    while (pos < codebookBytes_) {
      if (count == codewords_)
        dfail("more codewords than the header's " + std::to_string(codewords_));
      if (indirect) {
        if (kernels::readBits(book + indexTableAt_, count * std::uint64_t(addressBits_),
                              addressBits_) != pos)
          dfail("index table entry " + std::to_string(count) + " is not codeword " +
                std::to_string(count));
      } else {
        startBits[pos / 64] |= std::uint64_t(1) << (pos % 64);
      }
      ++count;
      pos += codewordLength(book + codebookAt_ + pos, codebookBytes_ - pos, bits_, src);
    }
    if (count != codewords_)
      dfail(std::to_string(count) + " codewords, the header says " + std::to_string(codewords_));
  }
  // Every offset-volume entry names a codeword.
  const bool direct = compressed && !indirect;
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::uint64_t e = kernels::readBits(base, i * std::uint64_t(offsetBits_), offsetBits_);
    const bool ok =
        direct ? e < codebookBytes_ && (startBits[e / 64] >> (e % 64) & 1) : e < codewords_;
    if (!ok) dfail("offset volume entry " + std::to_string(i) + " names no codeword");
  }
}

kernels::VqView Layout::view(const std::byte* base) const {
  kernels::VqView v;
  kernels::VqDecoder& d = v.decoder;
  d.data = reinterpret_cast<const std::uint8_t*>(base ? base : data_.data());
  d.book = !sharedBook() ? d.data
           : base        ? d.data + deviceBookAt()
                         : reinterpret_cast<const std::uint8_t*>(book_.data());
  d.indexTableAt = indexTableAt_, d.codebookAt = codebookAt_;
  d.bricksX = (info_.dims.x + 3) / 4, d.bricksY = (info_.dims.y + 3) / 4;
  d.bits = bits_, d.offsetBits = offsetBits_, d.addressBits = addressBits_;
  d.compressed = flags_ & kCompressed, d.indirect = flags_ & kIndirect;
  d.bias = float(bias_);
  v.setDims(info_.dims.x, info_.dims.y, info_.dims.z);
  v.cacheId = cacheId_;
  return v;
}

std::uint64_t Layout::deviceBookAt() const { return sharedBook() ? align64(data_.size()) : 0; }

std::vector<std::byte> Layout::joinedBytes() const {
  std::vector<std::byte> out(deviceBookAt() + book_.size(), std::byte{0});
  std::copy(data_.begin(), data_.end(), out.begin());
  if (sharedBook())
    std::copy(book_.begin(), book_.end(), out.begin() + std::ptrdiff_t(deviceBookAt()));
  return out;
}

RangeGrid Layout::rangeGrid() const { return brickRangeGrid(view(), info_.type); }

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  const Layout layout(info, sections);
  return decodeBricks(layout.view(), info.type, info.spacing);
}

}  // namespace voxwall::codec::vq
