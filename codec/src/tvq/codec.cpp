// The tvq codec's encoder: planning the sub-volumes' chapters, training their codebooks, coding the
// blocks and writing the sections (layout.cpp reads them back). The byte layout is documented in
// tvq_codec.hpp and our reading of the paper in docs/tvq.md.
#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/common.hpp>
#include <limits>
#include <queue>
#include <random>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>
#include <voxwall/core/text.hpp>

#include "format.hpp"
#include "lbg.hpp"

namespace voxwall::codec::tvq {
namespace {

// A codevector is worth its storage (its coefficients at 16 bits) only if it serves several
// blocks: a chapter gets at most one codevector per kMembersPerCodevector of its blocks.
constexpr std::uint64_t kMembersPerCodevector = 8;
constexpr std::uint64_t kTrainingPerCodevector = 16;

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// A chapter's training material and statistics in one sub-volume.
struct Chapter {
  int dims = 0;
  std::vector<int> coefs;
  std::vector<float> vectors;  // members x dims, only while its sub-volume is trained
  std::vector<double> sum;     // of the members, per dimension
  std::uint64_t members = 0;
  double zeroError = 0, meanError = 0;  // squared error against the zero vector, the centroid
  // Modelled distortion with n codevectors (high-rate: meanError x n^(-2/dims)); 0 once every
  // member can have its own.
  double distortion(std::uint64_t n) const {
    if (members == 0) return 0;
    if (n == 0) return zeroError;
    if (n >= members) return 0;
    return meanError * std::pow(double(n), -2.0 / double(dims));
  }
  std::uint64_t cap() const {
    return std::max<std::uint64_t>(members ? 1 : 0, members / kMembersPerCodevector);
  }
};

// Per partition, the order in which codevectors are handed out: always to the chapter whose
// modelled distortion drops most per bit of codebook storage (at the end the slopes are equal:
// Ramamurthi and Gersho's equal mean distortion per codevector, weighted by storage). Step i
// records the chapter, the drop per bit (made non-increasing) and the totals after it.
struct PartitionCurve {
  std::vector<std::uint8_t> chapter;  // per step
  std::vector<double> slope;          // distortion drop per storage bit, non-increasing
  std::vector<double> distortion;     // after step i; [0] before any
  std::vector<double> bookBits;       // codebook storage after step i; [0] = 0
  std::size_t maxSteps() const { return chapter.size(); }
};

PartitionCurve partitionCurve(const std::vector<Chapter>& chapters) {
  PartitionCurve curve;
  std::vector<std::uint64_t> n(chapters.size(), 0);
  using Step = std::pair<double, std::size_t>;
  std::priority_queue<Step> gains;
  auto push = [&](std::size_t c) {
    if (n[c] < chapters[c].cap())
      gains.push({(chapters[c].distortion(n[c]) - chapters[c].distortion(n[c] + 1)) /
                      (16.0 * double(chapters[c].dims)),
                  c});
  };
  double total = 0, bits = 0;
  for (std::size_t c = 0; c < chapters.size(); ++c) total += chapters[c].distortion(0), push(c);
  curve.distortion.push_back(total), curve.bookBits.push_back(0);
  const std::uint64_t most = (std::uint64_t(1) << kMaxCodeBits) - 1;
  while (curve.chapter.size() < most && !gains.empty()) {
    const auto [slope, c] = gains.top();
    gains.pop();
    total -= slope * 16.0 * double(chapters[c].dims), bits += 16.0 * double(chapters[c].dims);
    ++n[c];
    curve.chapter.push_back(std::uint8_t(c));
    curve.slope.push_back(curve.slope.empty() ? slope : std::min(slope, curve.slope.back()));
    curve.distortion.push_back(std::max(0.0, total)), curve.bookBits.push_back(bits);
    push(c);
  }
  return curve;
}

// What the encoder knows of a sub-volume before training.
struct SubPlan {
  glm::ivec3 first{}, extent{};
  std::uint32_t background = 0;
  std::uint64_t coded = 0;
  std::vector<std::uint8_t> cls;  // per local block; kUncoded for a ZERO block without record
  std::vector<std::uint16_t> dc;  // per local block
  std::array<std::vector<Chapter>, 3> chapters;
  std::array<PartitionCurve, 3> curves;
  // Chosen by allocate():
  std::array<int, 3> bits{};                        // as stored
  std::array<std::vector<std::uint64_t>, 3> sizes;  // chapter sizes
};

// The Lagrangian allocation (Shoham and Gersho): each partition takes the codebook size that
// minimizes distortion + lambda x (its codebook storage + its code bits in every coded block),
// among the sizes 2^b - 1 (b <= maxBits[p]) and the point where a codevector no longer pays
// for its storage (slope < lambda). lambda = 0: the largest codebooks the bits address.
void allocate(SubPlan& plan, double lambda, const std::array<int, 3>& maxBits) {
  for (int p = 0; p < 3; ++p) {
    const PartitionCurve& c = plan.curves[std::size_t(p)];
    std::size_t worth = 0;  // steps whose slope is at least lambda
    while (worth < c.maxSteps() && c.slope[worth] >= lambda) ++worth;
    double best = std::numeric_limits<double>::infinity();
    std::size_t steps = 0;
    for (int b = 0; b <= maxBits[std::size_t(p)]; ++b) {
      const std::size_t s = std::min<std::size_t>(worth, (std::size_t(1) << b) - 1);
      const double cost = c.distortion[s] +
                          lambda * (c.bookBits[s] + double(plan.coded) * double(std::bit_width(s)));
      if (cost < best) best = cost, steps = s;
    }
    plan.sizes[std::size_t(p)].assign(plan.chapters[std::size_t(p)].size(), 0);
    for (std::size_t i = 0; i < steps; ++i) ++plan.sizes[std::size_t(p)][c.chapter[i]];
    plan.bits[std::size_t(p)] = int(std::bit_width(steps));
  }
}

// The bits per partition within a budget of `codeBits` for the three codes: the split of least
// modelled distortion, each partition's codebook as large as its bits address (lambda = 0).
void allocateBits(SubPlan& plan, int codeBits) {
  double best = std::numeric_limits<double>::infinity();
  std::array<int, 3> pick{};
  auto distortion = [&](int p, int b) {
    const PartitionCurve& c = plan.curves[std::size_t(p)];
    return c.distortion[std::min<std::size_t>(c.maxSteps(), (std::size_t(1) << b) - 1)];
  };
  for (int a = 0; a <= std::min(kMaxCodeBits, codeBits); ++a)
    for (int b = 0; b <= std::min(kMaxCodeBits, codeBits - a); ++b) {
      const int c = std::min(kMaxCodeBits, codeBits - a - b);
      const double d = distortion(0, a) + distortion(1, b) + distortion(2, c);
      // Ties (saturated chapters) keep the fewer bits found first.
      if (d < best * (1 - 1e-12)) best = d, pick = {a, b, c};
    }
  allocate(plan, 0.0, pick);
}

// Bytes of the file's sections for the plans as allocated (what --bits-per-voxel searches).
std::uint64_t plannedBytes(const std::vector<SubPlan>& plans, int dcBits) {
  std::uint64_t bytes = kParamsBytes + 64 * 64 * 4 + 64 + plans.size() * kSubvolumeBytes;
  for (const SubPlan& s : plans) {
    for (int p = 0; p < 3; ++p)
      for (std::size_t c = 0; c < s.sizes[std::size_t(p)].size(); ++c)
        bytes += s.sizes[std::size_t(p)][c] * std::uint64_t(s.chapters[std::size_t(p)][c].dims) * 2;
    bytes += (Grid::volume(s.extent) + 63) / 64 * 8;
    const std::uint64_t record = std::uint64_t(dcBits + s.bits[0] + s.bits[1] + s.bits[2]);
    bytes += (s.coded * record + 7) / 8;
  }
  return bytes;
}

// A sub-volume's codebooks and its members' codes.
struct Coded {
  std::array<std::vector<std::vector<std::int16_t>>, 3> codebooks;  // [p][chapter]
  std::array<float, 3> scale{};
  std::array<std::vector<std::vector<std::uint32_t>>, 3> codes;  // [p][chapter][member]
};

// The encoder of a volume of scalar type T, stage by stage (run): the transform, the
// classification and the chapters' statistics, the allocation of code bits, the codebooks, the
// sections, and the PSNR of every progressive level.
template <class T>
class Encoder {
 public:
  Encoder(const VolumeSource& volume, const Params& params, Progress& progress, EncodeStats& stats)
      : volume_(volume),
        params_(params),
        progress_(progress),
        stats_(stats),
        workers_(resolveThreads(params.threads)),
        grid_(volume.dims, params.subvolumeVoxels / 4),
        window_(volume),
        blockCount_(Grid::volume(grid_.blocks)) {
    if (!volume.finite)
      throw std::invalid_argument(
          "the volume holds NaN or infinite values: the tvq codec codes finite numbers only");
    const auto [lowest, highest] = volume.dataRange();
    vmin_ = float(lowest);
    const float vmax = float(highest);
    range_ = vmax > vmin_ ? double(vmax) - double(vmin_) : 1.0;
  }

  CompressedVolume run() {
    auto t0 = std::chrono::steady_clock::now();
    transform();
    stats_.transformSeconds = seconds(t0);
    t0 = std::chrono::steady_clock::now();
    classifyAll();
    allocate();
    stats_.classifySeconds = seconds(t0);
    t0 = std::chrono::steady_clock::now();
    train();
    stats_.trainSeconds = seconds(t0);
    CompressedVolume cv = sections();
    measure(cv);
    return cv;
  }

 private:
  // The slices of the blocks at hand: a batch of blocks for the KLT, a row of sub-volumes after.
  void loadBlockRows(int firstRow, int rows) { window_.load(firstRow * 4, rows * 4); }
  void blockAt(glm::ivec3 b, float* out) const {
    for (int z = 0, i = 0; z < 4; ++z)
      for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x, ++i) {
          const int vx = std::min(b.x * 4 + x, volume_.dims.x - 1);
          const int vy = std::min(b.y * 4 + y, volume_.dims.y - 1);
          const int vz = std::min(b.z * 4 + z, volume_.dims.z - 1);
          out[i] = float(window_.at(vx, vy, vz));
        }
  }
  glm::ivec3 blockOfIndex(std::uint64_t i) const {
    const auto& b = grid_.blocks;
    return glm::ivec3{int(i % std::uint64_t(b.x)), int(i / std::uint64_t(b.x) % std::uint64_t(b.y)),
                      int(i / (std::uint64_t(b.x) * std::uint64_t(b.y)))};
  }

  // 1. The transform (KLT learned from the blocks, or the DCT), and what it fixes: the means'
  // quantization and each chapter's coefficients.
  void transform() {
    basis_ =
        params_.transform == Transform::Dct
            ? dctBasis()
            : kltBasis(
                  blockCount_, [&](std::uint64_t i, float* out) { blockAt(blockOfIndex(i), out); },
                  workers_, progress_,
                  [&](std::uint64_t first, std::uint64_t end) {
                    const int a = blockOfIndex(first).z, b = blockOfIndex(end - 1).z;
                    loadBlockRows(a, b - a + 1);
                  });
    dcLevels_ = (1 << params_.dcBits) - 1;
    dcLo_ = vmin_, dcStep_ = range_ / double(dcLevels_);
    maxError2_ = std::pow(params_.fidelity * range_, 2) * kBlockVoxels;
    for (int p = 0; p < 3; ++p)
      for (int c = 0; c < chapterCount(p); ++c)
        coefs_[std::size_t(p)].push_back(chapterCoefficients(basis_, p, firstChapterClass(p) + c));
  }

  // The coefficients of a sub-volume's blocks (local index, x fastest). Computed twice, for the
  // classification and again for training, so that the encoder holds one sub-volume's at a time.
  std::vector<float> transformed(const SubPlan& plan,
                                 const std::function<void(std::size_t, const float*)>& each) {
    const std::uint64_t local = Grid::volume(plan.extent);
    loadBlockRows(plan.first.z, plan.extent.z);
    std::vector<float> coefficients(local * kBlockVoxels);
    parallelFor(local, workers_, [&](std::size_t i) {
      const glm::ivec3 e = plan.extent;
      const glm::ivec3 b = plan.first + glm::ivec3{int(i % std::size_t(e.x)),
                                                   int(i / std::size_t(e.x) % std::size_t(e.y)),
                                                   int(i / (std::size_t(e.x) * std::size_t(e.y)))};
      float x[kBlockVoxels];
      blockAt(b, x);
      float* c = coefficients.data() + i * kBlockVoxels;
      basis_.forward(x, c);
      if (each) each(i, c);
    });
    return coefficients;
  }

  // 2. Classification and the chapters' statistics, per sub-volume.
  void classifyAll() {
    plans_.assign(grid_.subCount(), SubPlan{});
    progress_.begin("tvq: classify", plans_.size());
    for (std::uint64_t si = 0; si < plans_.size(); ++si) {
      classifySubvolume(si);
      stats_.coded += plans_[si].coded;
      progress_.advance();
    }
    progress_.end();
    stats_.blocks = blockCount_;
  }

  void classifySubvolume(std::uint64_t si) {
    SubPlan& plan = plans_[si];
    plan.first = grid_.first(si), plan.extent = grid_.extent(si);
    const std::uint64_t local = Grid::volume(plan.extent);
    plan.cls.assign(local, 0), plan.dc.assign(local, 0);
    const std::vector<float> coefficients = transformed(plan, [&](std::size_t i, const float* c) {
      const double mean = double(c[0]) / 8.0;
      plan.dc[i] =
          std::uint16_t(std::clamp(std::lround((mean - dcLo_) / dcStep_), 0L, long(dcLevels_)));
      plan.cls[i] = std::uint8_t(classify(basis_, c, maxError2_, params_.classified));
    });
    // The background: the most common mean of the ZERO blocks.
    std::vector<std::uint64_t> histogram(std::size_t(dcLevels_) + 1, 0);
    for (std::uint64_t i = 0; i < local; ++i)
      if (plan.cls[i] == kZero) ++histogram[plan.dc[i]];
    plan.background =
        std::uint32_t(std::max_element(histogram.begin(), histogram.end()) - histogram.begin());
    for (int p = 0; p < 3; ++p)
      for (int c = 0; c < chapterCount(p); ++c) {
        Chapter ch;
        ch.coefs = coefs_[std::size_t(p)][std::size_t(c)];
        ch.dims = int(ch.coefs.size());
        ch.sum.assign(std::size_t(ch.dims), 0.0);
        plan.chapters[std::size_t(p)].push_back(std::move(ch));
      }
    for (std::uint64_t i = 0; i < local; ++i) {
      const int cls = plan.cls[i];
      ++stats_.classBlocks[std::size_t(cls)];
      if (cls == kZero) {
        if (plan.dc[i] == plan.background)
          plan.cls[i] = kUncoded;
        else
          ++plan.coded;
        continue;
      }
      ++plan.coded;
      const float* c = coefficients.data() + i * kBlockVoxels;
      for (int p = 0; p < 3; ++p) {
        if (cls < firstChapterClass(p)) continue;
        Chapter& ch = plan.chapters[std::size_t(p)][std::size_t(cls - firstChapterClass(p))];
        for (int j = 0; j < ch.dims; ++j) {
          const double v = c[ch.coefs[std::size_t(j)]];
          ch.sum[std::size_t(j)] += v, ch.zeroError += v * v;
        }
        ++ch.members;
      }
    }
    for (int p = 0; p < 3; ++p) {
      for (Chapter& ch : plan.chapters[std::size_t(p)]) {
        double norm2 = 0;
        for (double v : ch.sum) {
          const double mean = v / double(std::max<std::uint64_t>(1, ch.members));
          norm2 += mean * mean;
        }
        ch.meanError = std::max(0.0, ch.zeroError - double(ch.members) * norm2);
      }
      plan.curves[std::size_t(p)] = partitionCurve(plan.chapters[std::size_t(p)]);
    }
  }

  // 3. The allocation: --codebook-bits split among the partitions, or, for a size target, the
  // Lagrangian trade-off whose file fits it (bisection on lambda).
  void allocate() {
    codeBits_ = params_.codeBits;
    if (params_.targetBitsPerVoxel > 0) {
      allocateForSize();
    } else {
      for (SubPlan& s : plans_) allocateBits(s, codeBits_);
    }
    stats_.codeBits = codeBits_;
    stats_.subvolumes = int(plans_.size());
  }

  void allocateForSize() {
    const double target = params_.targetBitsPerVoxel * double(volume_.voxelCount()) / 8.0;
    const std::array<int, 3> most{kMaxCodeBits, kMaxCodeBits, kMaxCodeBits};
    auto bytesAt = [&](double lambda) {
      for (SubPlan& s : plans_) tvq::allocate(s, lambda, most);
      return double(plannedBytes(plans_, params_.dcBits));
    };
    if (bytesAt(std::numeric_limits<double>::infinity()) > target) {
      throw std::invalid_argument(formatLine(
          "--bits-per-voxel %g is below the smallest tvq file of this volume (%.3f bits per "
          "voxel with --dc-bits %d: the means and occupancy alone); lower --dc-bits or raise the "
          "target",
          params_.targetBitsPerVoxel,
          8.0 * bytesAt(std::numeric_limits<double>::infinity()) / double(volume_.voxelCount()),
          params_.dcBits));
    }
    double lo = -40, hi = 40;  // log2 of lambda, in squared value units per bit
    // Every partition at its largest codebooks: a file within 2% of the target meets it; one
    // further below cannot, and says how far it goes and what codes more.
    const double largest = bytesAt(0);
    if (largest <= target) {
      if (largest < 0.98 * target)
        throw std::invalid_argument(formatLine(
            "--bits-per-voxel %g is above the largest tvq file of this volume (%.3f bits per "
            "voxel with %d-bit codes in every partition at --fidelity %g; a record is at most "
            "%d + --dc-bits bits per 4^3 block): lower the target or --fidelity, or use ksvd or "
            "zfp for this rate",
            params_.targetBitsPerVoxel, 8.0 * largest / double(volume_.voxelCount()), kMaxCodeBits,
            params_.fidelity, 3 * kMaxCodeBits));
      hi = -std::numeric_limits<double>::infinity();
    } else {
      for (int i = 0; i < 60; ++i) {
        const double mid = 0.5 * (lo + hi);
        (bytesAt(std::exp2(mid)) > target ? lo : hi) = mid;
      }
    }
    bytesAt(std::exp2(hi));
    codeBits_ = 0;
    for (const SubPlan& s : plans_)
      codeBits_ = std::max(codeBits_, s.bits[0] + s.bits[1] + s.bits[2]);
  }

  // 4. The chapters' codebooks (LBG), quantized to 16 bits per coefficient with a scale per
  // partition, and every member's nearest codevector.
  void train() {
    progress_.begin("tvq: train codebooks (LBG)", plans_.size() * 3 * 9);
    coded_.assign(plans_.size(), Coded{});
    std::mt19937_64 rng(params_.seed);
    for (std::size_t si = 0; si < plans_.size(); ++si) {
      gatherMembers(plans_[si]);
      for (int p = 0; p < 3; ++p) trainPartition(plans_[si], p, coded_[si], rng);
    }
    progress_.end();
  }

  // The members' vectors, in block order (the order the records take their codes in).
  void gatherMembers(SubPlan& plan) {
    const std::vector<float> coefficients = transformed(plan, {});
    for (std::size_t i = 0; i < plan.cls.size(); ++i) {
      const int cls = plan.cls[i];
      if (cls == kUncoded || cls == kZero) continue;
      const float* c = coefficients.data() + i * kBlockVoxels;
      for (int p = 0; p < 3; ++p) {
        if (cls < firstChapterClass(p)) continue;
        Chapter& ch = plan.chapters[std::size_t(p)][std::size_t(cls - firstChapterClass(p))];
        for (int k : ch.coefs) ch.vectors.push_back(c[k]);
      }
    }
  }

  void trainPartition(SubPlan& plan, int p, Coded& out, std::mt19937_64& rng) {
    auto& chapters = plan.chapters[std::size_t(p)];
    std::vector<std::vector<float>> books(chapters.size());
    float peak = 0;
    for (std::size_t c = 0; c < chapters.size(); ++c) {
      const std::uint64_t size = plan.sizes[std::size_t(p)][c];
      if (size > 0) {
        books[c] = trainChapter(chapters[c], size, rng);
        for (float v : books[c]) peak = std::max(peak, std::abs(v));
      }
      progress_.advance();
    }
    for (std::size_t c = chapters.size(); c < 9; ++c) progress_.advance();
    const float scale = peak > 0 ? peak / 32767.0f : 1.0f;
    out.scale[std::size_t(p)] = scale;
    out.codebooks[std::size_t(p)].resize(chapters.size());
    out.codes[std::size_t(p)].resize(chapters.size());
    for (std::size_t c = 0; c < chapters.size(); ++c) {
      std::vector<std::int16_t>& q = out.codebooks[std::size_t(p)][c];
      std::vector<float> dequantized(books[c].size());
      q.resize(books[c].size());
      for (std::size_t i = 0; i < books[c].size(); ++i) {
        q[i] = std::int16_t(std::clamp(std::lround(books[c][i] / scale), -32767L, 32767L));
        dequantized[i] = float(q[i]) * scale;
      }
      plan.sizes[std::size_t(p)][c] = q.size() / std::size_t(std::max(1, chapters[c].dims));
      if (!q.empty())
        out.codes[std::size_t(p)][c] =
            nearestCodevectors(chapters[c].vectors, chapters[c].dims, dequantized, workers_);
      chapters[c].vectors = {};
      chapters[c].vectors.shrink_to_fit();
    }
  }

  // A chapter's codebook of `size` codevectors, trained on a random sample of its members beyond
  // trainingVectors (at least kTrainingPerCodevector per codevector: fewer overfit).
  std::vector<float> trainChapter(const Chapter& ch, std::uint64_t size, std::mt19937_64& rng) {
    std::vector<float> sample;
    const std::uint64_t train =
        std::max<std::uint64_t>(params_.trainingVectors, kTrainingPerCodevector * size);
    if (ch.members > train) {
      std::vector<std::uint64_t> pick(ch.members);
      for (std::uint64_t m = 0; m < ch.members; ++m) pick[m] = m;
      std::shuffle(pick.begin(), pick.end(), rng);
      pick.resize(train);
      std::sort(pick.begin(), pick.end());
      sample.reserve(pick.size() * std::size_t(ch.dims));
      for (std::uint64_t m : pick)
        sample.insert(sample.end(), ch.vectors.begin() + std::ptrdiff_t(m * std::uint64_t(ch.dims)),
                      ch.vectors.begin() + std::ptrdiff_t((m + 1) * std::uint64_t(ch.dims)));
    }
    return trainLbg(sample.empty() ? std::span<const float>(ch.vectors) : sample, ch.dims, size,
                    params_.iterations, rng(), workers_);
  }

  // 5. The sections.
  CompressedVolume sections() {
    CompressedVolume cv;
    cv.info = volumeInfo(volume_.headerVolume(), TvqCodecEntry::kId);
    std::vector<std::byte> basisBytes, subBytes, bookBytes, occBytes, recBytes;
    {
      ByteWriter w(basisBytes);
      for (float v : basis_.rows) w.put<float>(v);
      for (std::uint8_t z : basis_.zone) w.put<std::uint8_t>(z);
    }
    ByteWriter sw(subBytes), bw(bookBytes), ow(occBytes);
    std::array<double, 3> bitSum{};
    for (std::size_t si = 0; si < plans_.size(); ++si) {
      const SubPlan& plan = plans_[si];
      const Coded& out = coded_[si];
      for (int p = 0; p < 3; ++p) sw.put<std::uint8_t>(std::uint8_t(plan.bits[std::size_t(p)]));
      sw.put<std::uint8_t>(0);
      sw.put<std::uint32_t>(plan.background);
      sw.put<std::uint64_t>(plan.coded);
      for (int p = 0; p < 3; ++p) sw.put<float>(out.scale[std::size_t(p)]);
      for (int p = 0; p < 3; ++p) {
        bitSum[std::size_t(p)] += plan.bits[std::size_t(p)];
        for (std::uint64_t s : plan.sizes[std::size_t(p)]) sw.put<std::uint32_t>(std::uint32_t(s));
      }
      for (int p = 0; p < 3; ++p)
        for (const auto& book : out.codebooks[std::size_t(p)])
          for (std::int16_t v : book) bw.put<std::int16_t>(v);
      writeRecords(plan, out, ow, recBytes);
    }
    for (int p = 0; p < 3; ++p)
      stats_.meanCodeBits[std::size_t(p)] =
          bitSum[std::size_t(p)] / double(std::max<std::size_t>(1, plans_.size()));
    stats_.codebookBytes = bookBytes.size(), stats_.recordBytes = recBytes.size();
    stats_.occupancyBytes = occBytes.size();
    cv.sections.push_back({kParams, paramsSection()});
    cv.sections.push_back({kBasis, std::move(basisBytes)});
    cv.sections.push_back({kSubvolumes, std::move(subBytes)});
    cv.sections.push_back({kCodebooks, std::move(bookBytes)});
    cv.sections.push_back({kOccupancy, std::move(occBytes)});
    cv.sections.push_back({kRecords, std::move(recBytes)});
    return cv;
  }

  std::vector<std::byte> paramsSection() const {
    std::vector<std::byte> bytes;
    ByteWriter w(bytes);
    w.put<std::uint32_t>(std::uint32_t(params_.transform));
    w.put<std::uint32_t>(std::uint32_t(grid_.s));
    w.put<std::uint32_t>(std::uint32_t(params_.dcBits));
    w.put<std::uint32_t>(params_.classified ? 1u : 0u);
    w.put<std::uint32_t>(std::uint32_t(codeBits_));
    w.put<std::uint32_t>(0);
    w.put<double>(params_.fidelity);
    w.put<double>(dcLo_);
    w.put<double>(dcStep_);
    for (int l = 0; l < kProgressiveLevels; ++l) w.put<double>(0.0);  // measured below
    w.put<std::uint64_t>(plans_.size());
    return bytes;
  }

  // A sub-volume's occupancy words and records: the mean and a code per partition for every
  // block but the uncoded ones.
  void writeRecords(const SubPlan& plan, const Coded& out, ByteWriter& ow,
                    std::vector<std::byte>& recBytes) const {
    const std::uint64_t local = Grid::volume(plan.extent);
    std::vector<std::uint64_t> words((local + 63) / 64, 0);
    const int recordBits = params_.dcBits + plan.bits[0] + plan.bits[1] + plan.bits[2];
    std::vector<std::uint8_t> records((plan.coded * std::uint64_t(recordBits) + 7) / 8, 0);
    std::uint64_t bit = 0;
    auto putBits = [&](std::uint64_t value, int bits) {
      for (int i = 0; i < bits; ++i, ++bit)
        if ((value >> i) & 1) records[bit >> 3] |= std::uint8_t(1u << (bit & 7));
    };
    std::array<std::vector<std::uint64_t>, 3> next;    // next member per chapter
    std::array<std::vector<std::uint64_t>, 3> offset;  // first global index per chapter
    for (int p = 0; p < 3; ++p) {
      next[std::size_t(p)].assign(plan.chapters[std::size_t(p)].size(), 0);
      std::uint64_t o = 1;
      for (std::uint64_t s : plan.sizes[std::size_t(p)])
        offset[std::size_t(p)].push_back(o), o += s;
    }
    for (std::uint64_t i = 0; i < local; ++i) {
      const int cls = plan.cls[i];
      if (cls == kUncoded) continue;
      words[i >> 6] |= std::uint64_t(1) << (i & 63);
      putBits(plan.dc[i], params_.dcBits);
      for (int p = 0; p < 3; ++p) {
        std::uint64_t k = 0;
        if (cls != kZero && cls >= firstChapterClass(p)) {
          const std::size_t c = std::size_t(cls - firstChapterClass(p));
          const std::uint64_t member = next[std::size_t(p)][c]++;
          if (plan.sizes[std::size_t(p)][c] > 0)
            k = offset[std::size_t(p)][c] + out.codes[std::size_t(p)][c][member];
        }
        putBits(k, plan.bits[std::size_t(p)]);
      }
    }
    for (std::uint64_t word : words) ow.put<std::uint64_t>(word);
    recBytes.insert(recBytes.end(), reinterpret_cast<const std::byte*>(records.data()),
                    reinterpret_cast<const std::byte*>(records.data() + records.size()));
  }

  // 6. The PSNR of every progressive level, measured on the decoded volume, into the params.
  void measure(CompressedVolume& cv) {
    progress_.begin("tvq: measure PSNR", kProgressiveLevels);
    {
      const Layout layout(cv.info, cv.view());
      for (int l = 0; l < kProgressiveLevels; ++l) {
        stats_.levelPsnr[std::size_t(l)] = brickPsnr(volume_, layout.view(nullptr, l));
        progress_.advance();
      }
    }
    progress_.end();
    for (int l = 0; l < kProgressiveLevels; ++l) {
      double v = stats_.levelPsnr[std::size_t(l)];
      std::memcpy(cv.sections[0].second.data() + 48 + 8 * std::size_t(l), &v, sizeof v);
    }
  }

  const VolumeSource& volume_;
  const Params& params_;
  Progress& progress_;
  EncodeStats& stats_;
  const int workers_;
  const Grid grid_;
  SliceWindow<T> window_;
  const std::uint64_t blockCount_;
  float vmin_ = 0;
  double range_ = 1;
  Basis basis_;
  int dcLevels_ = 255;
  double dcLo_ = 0, dcStep_ = 1, maxError2_ = 0;
  std::array<std::vector<std::vector<int>>, 3> coefs_;  // [partition][chapter]
  std::vector<SubPlan> plans_;
  int codeBits_ = 0;
  std::vector<Coded> coded_;
};

}  // namespace

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats) {
  return encode(*memorySource(volume), params, progress, stats);
}

CompressedVolume encode(const VolumeSource& volume, const Params& params, Progress& progress,
                        EncodeStats* stats) {
  if (params.dcBits < 1 || params.dcBits > 16)
    throw std::invalid_argument("--dc-bits must be in 1..16");
  if (params.codeBits < 0 || params.codeBits > kMaxCodeBitsTotal)
    throw std::invalid_argument("--codebook-bits must be in 0.." +
                                std::to_string(kMaxCodeBitsTotal));
  if (params.subvolumeVoxels < 4 || params.subvolumeVoxels > 4 * kMaxSubvolumeBlocks ||
      params.subvolumeVoxels % 4)
    throw std::invalid_argument("--subvolume must be a multiple of 4 in 4.." +
                                std::to_string(4 * kMaxSubvolumeBlocks) + " voxels");
  if (!(params.fidelity >= 0 && params.fidelity < 1))
    throw std::invalid_argument("--fidelity must be in [0, 1)");
  if (params.iterations < 1) throw std::invalid_argument("--iterations must be at least 1");
  if (params.trainingVectors < 1)
    throw std::invalid_argument("tvq: training vectors must be at least 1");
  EncodeStats local;
  EncodeStats& s = stats ? *stats : local;
  s = EncodeStats{};
  return dispatchScalar(
      volume.type, [&](auto t) { return Encoder<decltype(t)>(volume, params, progress, s).run(); });
}

}  // namespace voxwall::codec::tvq
