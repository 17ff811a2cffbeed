// The ksvd codec's registry entry: its compress options and report, info lines, render payload
// and samples.
#include <cmath>
#include <mutex>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/core/text.hpp>

#include "format.hpp"

namespace voxwall::codec::ksvd {
namespace {

class Payload final : public RenderPayload {
 public:
  Payload(const VolumeInfo& info, const SectionSet& sections) : layout_(info, sections) {}
  RangeGrid rangeGrid() const override { return layout_.rangeGrid(); }
  // The render buffer and the pairs joined, made when a device backend first asks (a CPU rank
  // reads the pairs where the file is mapped).
  std::span<const std::byte> bytes() const override {
    std::call_once(joinOnce_, [this] { joined_ = layout_.joinedBytes(); });
    return joined_;
  }
  AnyView view(const std::byte* base) const override {
    return layout_.withView([](const auto& v) { return AnyView(v); }, base);
  }

 private:
  Layout layout_;
  mutable std::once_flag joinOnce_;
  mutable std::vector<std::byte> joined_;
};

std::string encodeReport(const EncodeStats& s, const Volume& v, bool sizeTarget) {
  std::string report = formatLine(
      "\n  %llu bricks (%llu constant), %llu blocks coded with the DC atom and %llu pairs of "
      "learned atoms (%.2f per block, at most %d in all)",
      (unsigned long long)s.bricks, (unsigned long long)s.constantBricks,
      (unsigned long long)s.codedBlocks, (unsigned long long)s.pairs,
      s.codedBlocks ? double(s.pairs) / double(s.codedBlocks) : 0.0, s.sparsity);
  report += formatLine(
      "\n  dictionary %d atoms of %d-bit values (%s), pairs %s (%d bits: %d for the atom, %d for "
      "the "
      "coefficient), brick table, DC coefficients and counts %s: %.3f bits per voxel",
      s.atoms, s.atomBits, humanBytes(double(s.dictionaryBytes)).c_str(),
      humanBytes(double(s.pairBytes)).c_str(), s.indexBits + s.coefficientBits, s.indexBits,
      s.coefficientBits, humanBytes(double(s.brickBytes + s.countBytes)).c_str(),
      bitsPerVoxel(s.dictionaryBytes + s.pairBytes + s.brickBytes + s.countBytes, v));
  report += formatLine(
      "\n  K-SVD: %d iterations at sparsity %d on a coreset of %llu of %llu blocks in %.2fs "
      "(training RMSE %.4g of the range); coding %.2fs",
      s.iterations, s.trainSparsity, (unsigned long long)s.coreset,
      (unsigned long long)s.codedBlocks, s.trainSeconds, s.trainingRmse, s.codeSeconds);
  if (s.levels > 1) {
    report +=
        formatLine("\n  %d levels (--lod), the coarser ones %.1f%% of the pairs; PSNR per level",
                   s.levels, s.pairs ? 100.0 * double(s.levelPairs) / double(s.pairs) : 0.0);
    for (double p : s.levelPsnr)
      report += std::isinf(p) ? std::string(" exact") : formatLine(" %.2f", p);
    report += " dB";
    if (sizeTarget)  // the target's bytes are shared with the pyramid
      report += formatLine(
          "\n  the coarser levels take %.1f%% of this size target's pairs: without render --lod, "
          "--levels 1 gives them to level 0 (a better picture at the same size)",
          s.pairs ? 100.0 * double(s.levelPairs) / double(s.pairs) : 0.0);
  }
  report += std::isinf(s.psnr) ? std::string("\n  exact (every brick constant)")
                               : formatLine("\n  PSNR %.2f dB", s.psnr);
  return report;
}

class KsvdCodec final : public StreamingCodecOf<KsvdCodecEntry> {
 public:
  std::string_view summary() const override {
    return "blocks as sparse combinations of a K-SVD dictionary learned on a coreset (Gobbetti "
           "et al., COVRA), lossy; any scalar type, the only compressed codec for float32";
  }

  std::vector<CodecOption> options() const override {
    return {
        {"--block",
         "ksvd codec: block side M in voxels (4, 6 or 8; default 6, but a --bits-per-voxel "
         "target without --block codes 4 and 6 and keeps the higher PSNR)",
         ""},
        {"--atoms",
         "ksvd codec: dictionary atoms K (2..65536; default 1024, at most one per 16 coded blocks "
         "and, with --bits-per-voxel, as many as fit in a quarter of the file at 16 bits a "
         "value)",
         ""},
        {"--sparsity", "ksvd codec: pairs (atom, coefficient) per block at most, S", "8"},
        {"--coefficient-bits",
         "ksvd codec: bits of a pair's quantized coefficient (2..23, at most 24 less the atom "
         "index's; default: 24 less the index's, or with --bits-per-voxel the better PSNR of the "
         "rate's width and one bit more, the rate's width being 6 below 0.35 bits per voxel, 7 "
         "below 0.75, 8 below 1.5)",
         ""},
        {"--mean-bits",
         "ksvd codec: bits of a block's mean, stored apart from its pairs in steps of its brick's "
         "range (1..24; default: one less than --coefficient-bits)",
         ""},
        {"--atom-bits",
         "ksvd codec: bits of a dictionary atom's stored value, with a scale per atom (4..16; "
         "default 8, or with --bits-per-voxel below 0.75 6; 16 stores them as files before this "
         "option did)",
         ""},
        {"--tolerance",
         "ksvd codec: stop a block's code at this RMS error, as a fraction of the value range "
         "(the paper uses 0.015); also the spread below which a brick is stored as constant",
         "0"},
        {"--coreset",
         "ksvd codec: training blocks, a count (> 1) or a fraction of the coded blocks (<= 1)",
         "32768"},
        {"--iterations", "ksvd codec: K-SVD iterations", "25"},
        {"--levels",
         "ksvd codec: pyramid levels for render --lod, each half the resolution of the one "
         "before (1: none; default: until a level fits in one brick, at most 8)",
         ""},
        {"--bits-per-voxel",
         "ksvd codec: the lowest price per pair (the squared error a pair must take off its "
         "block) whose file fits this size (and the "
         "default dictionary's atoms as many as a quarter of it holds at 16 bits); --sparsity caps "
         "the pairs per block, 16 "
         "by default; --block defaults to the better of 4 and 6, then --coefficient-bits to the "
         "better of the rate's width and one bit more (up to three encodes)",
         ""}};
  }

  static Params paramsOf(const CodecOptionValues& options) {
    Params p;
    p.targetBitsPerVoxel = options.number("--bits-per-voxel", 0, 1e-9, 64);
    p.blockSide = options.integer("--block", 6, 4, 8);
    p.atoms = options.integer("--atoms", 0, 2, 1 << 16);
    p.sparsity = options.integer("--sparsity", 8, 1, 255);
    p.coefficientBits = options.integer("--coefficient-bits", 0, 2, 23);
    p.meanBits = options.integer("--mean-bits", 0, 1, 24);
    p.atomBits = options.integer("--atom-bits", 0, kMinAtomBits, kWideAtomBits);
    p.tolerance = options.number("--tolerance", 0, 0, 0.999);
    p.coreset = options.number("--coreset", 0, 1e-9, 1e15);
    p.iterations = options.integer("--iterations", 25, 0, 10000);
    p.levels = options.integer("--levels", 0, 1, kernels::kKsvdMaxLevels);
    // With a size target, --sparsity caps the pairs per block (16 unless given).
    if (p.targetBitsPerVoxel > 0 && !options.given("--sparsity")) p.sparsity = 16;
    if (p.coreset > 1 && p.coreset != std::floor(p.coreset))
      throw std::invalid_argument("--coreset must be a whole count (> 1) or a fraction (<= 1)");
    p.threads = options.threads;
    return p;
  }

  // Streams: a row of bricks of the input in memory at a time, besides the coarser levels.
  CompressedVolume encodeSource(const VolumeSource& source, const CodecOptionValues& options,
                                Progress& progress, std::string& report) const override {
    const Params p = paramsOf(options);
    if (p.targetBitsPerVoxel > 0)
      return encodeBest(source, p, !options.given("--block"), !options.given("--coefficient-bits"),
                        progress, report);
    EncodeStats s;
    CompressedVolume out = ksvd::encode(source, p, progress, &s);
    report = encodeReport(s, source.headerVolume(), false);
    return out;
  }

  // A size target searches what the options leave open, keeping the higher PSNR (docs/ksvd.md):
  // without --block, blocks of 4^3 and of 6^3 are both coded (small blocks carry more detail per
  // pair but a mean and a count bit per 64 voxels, which noise, with no constant bricks, pays
  // everywhere); then, without --coefficient-bits, the kept side is coded again with
  // coefficients one bit wider than the rate's width (fewer pairs, each rounded half as
  // coarsely: on the MRI template at 0.5 bits per voxel 8 bits beat 7 by 0.4 dB, on the MRI at
  // 1 mm 7 beat 8 by 0.3).
  struct Try {
    std::string what;
    int side = 0;
    CompressedVolume out;
    EncodeStats stats;
    std::string refused;
  };
  static Try encodeTry(const VolumeSource& source, const Params& p, std::string what,
                       Progress& progress, const std::string& outer) {
    Try t{std::move(what), p.blockSide, {}, {}, {}};
    progress.setPrefix(outer + t.what + ": ");
    try {
      t.out = ksvd::encode(source, p, progress, &t.stats);
    } catch (const SizeTargetTooSmall& e) {
      t.refused = e.what();
    }
    progress.setPrefix(outer);
    return t;
  }
  // The better of two tries (a refused one never wins unless both are), with the report's line.
  static Try keepBetter(Try a, Try b, const char* option, std::string& line) {
    const bool aWins = a.refused.empty() && (!b.refused.empty() || a.stats.psnr >= b.stats.psnr);
    Try& best = aWins ? a : b;
    const Try& other = aWins ? b : a;
    if (best.refused.empty())
      line += other.refused.empty()
                  ? formatLine("\n  %s (PSNR %.2f dB) over %s (%.2f dB): both coded, %s codes one",
                               best.what.c_str(), best.stats.psnr, other.what.c_str(),
                               other.stats.psnr, option)
                  : formatLine("\n  %s, since %s", best.what.c_str(), other.refused.c_str());
    return std::move(best);
  }
  static CompressedVolume encodeBest(const VolumeSource& source, Params p, bool searchSide,
                                     bool searchWidth, Progress& progress, std::string& report) {
    const std::string outer = progress.prefix();
    const auto sideName = [](int side) { return formatLine("blocks of %d^3", side); };
    std::string lines;
    Params six = p;
    p.blockSide = searchSide ? 4 : p.blockSide, six.blockSide = 6;
    Try best = encodeTry(source, p, sideName(p.blockSide), progress, outer);
    if (searchSide)
      best = keepBetter(std::move(best), encodeTry(source, six, sideName(6), progress, outer),
                        "--block", lines);
    if (!best.refused.empty()) throw SizeTargetTooSmall(best.refused);
    const int width = best.stats.coefficientBits;
    if (searchWidth && width + 1 + best.stats.indexBits <= kMaxPairBits) {
      p.blockSide = best.side, p.coefficientBits = width + 1;
      const auto widthName = [](int bits) { return formatLine("coefficients of %d bits", bits); };
      best.what = widthName(width);
      best =
          keepBetter(std::move(best), encodeTry(source, p, widthName(width + 1), progress, outer),
                     "--coefficient-bits", lines);
    }
    report = encodeReport(best.stats, source.headerVolume(), true) + lines;
    return std::move(best.out);
  }

  // One dictionary for every step, learned on a coreset drawn from up to kTrainingSteps steps
  // spread over the series (stacked along z), as COVRA does for time-varying volumes; each step
  // is then coded with it, so the dictionary section is the same in every step and stored once.
  CompressedSeries encodeSeries(const SeriesSource& series, const CodecOptionValues& options,
                                Progress& progress, std::string& report) const override {
    if (options.stepsAlone || series.steps() == 1)
      return Codec::encodeSeries(series, options, progress, report);
    constexpr int kTrainingSteps = 8;
    Params p = paramsOf(options);
    const int steps = series.steps(), n = std::min(steps, kTrainingSteps);
    {
      Volume stacked;
      for (int i = 0; i < n; ++i) {
        const int k = n > 1 ? int((long long)i * (steps - 1) / (n - 1)) : 0;
        progress.setPrefix("dictionary: step " + std::to_string(k) + ": ");
        const std::unique_ptr<VolumeSource> source = series.open(k, progress);
        if (i == 0) {
          stacked = Volume::allocate({source->dims.x, source->dims.y, source->dims.z * n},
                                     source->type, source->spacing);
        }
        const std::size_t bytes = source->voxelCount() * scalarBytes(source->type);
        source->readSlices(0, source->dims.z,
                           std::span(stacked.data).subspan(std::size_t(i) * bytes, bytes));
      }
      stacked.computeRange();
      progress.setPrefix("dictionary: ");
      p.dictionary =
          std::make_shared<const std::vector<std::int16_t>>(learnDictionary(stacked, p, progress));
    }
    std::vector<CompressedVolume> coded;
    for (int k = 0; k < steps; ++k) {
      progress.setPrefix("step " + std::to_string(k + 1) + "/" + std::to_string(steps) + ": ");
      const std::unique_ptr<VolumeSource> source = series.open(k, progress);
      EncodeStats s;
      coded.push_back(ksvd::encode(*source, p, progress, &s));
      if (k == 0) report += encodeReport(s, source->headerVolume(), p.targetBitsPerVoxel > 0);
    }
    progress.setPrefix("");
    report += formatLine(
        "\n  one dictionary of %zu atoms for every step, learned on blocks of %d of the %d steps "
        "(--steps-alone: a dictionary a step)",
        p.dictionary->size() / std::size_t(p.blockSide * p.blockSide * p.blockSide), n, steps);
    return makeSeries(std::move(coded));
  }

  Volume decode(const VolumeInfo& info, const SectionSet& sections) const override {
    return ksvd::decode(info, sections);
  }

  InfoLines describe(const VolumeInfo& info, const SectionSet& sections) const override {
    const Layout layout(info, sections);
    const int m = layout.blockSide();
    InfoLines lines;
    lines.push_back({"blocks", formatLine("%d^3 voxels, %d^3 per brick; %llu bricks, %llu coded", m,
                                          blocksPerBrick(m), (unsigned long long)layout.bricks(),
                                          (unsigned long long)layout.codedBricks())});
    lines.push_back(
        {"dictionary", formatLine("%d atoms of %d %d-bit values (K-SVD, %d iterations on "
                                  "%llu training blocks)",
                                  layout.atoms(), m * m * m, layout.atomBits(), layout.iterations(),
                                  (unsigned long long)layout.coreset())});
    lines.push_back(
        {"pairs",
         formatLine(
             "%llu of %d bits (a %d-bit coefficient), at most %d per block with the "
             "DC atom's%s",
             (unsigned long long)layout.pairs(), layout.indexBits() + layout.coefficientBits(),
             layout.coefficientBits(), layout.sparsity(),
             layout.tolerance() > 0 ? formatLine(", tolerance %g", layout.tolerance()).c_str()
                                    : "")});
    std::string levels = formatLine("%d", layout.levels());
    if (layout.levels() > 1) {
      levels += " (render --lod), PSNR";
      for (int l = 0; l < layout.levels(); ++l) {
        const glm::ivec3 d = layout.levelDims(l);
        levels += formatLine("%s %dx%dx%d: ", l ? "," : "", d.x, d.y, d.z);
        levels += std::isinf(layout.levelPsnr(l)) ? std::string("exact")
                                                  : formatLine("%.2f dB", layout.levelPsnr(l));
      }
    }
    lines.push_back({"levels", levels});
    lines.push_back({"quality", std::isinf(layout.psnr())
                                    ? std::string("exact")
                                    : formatLine("lossy, PSNR %.2f dB", layout.psnr())});
    return lines;
  }

  std::unique_ptr<RenderPayload> open(const VolumeInfo& info,
                                      const SectionSet& sections) const override {
    return std::make_unique<Payload>(info, sections);
  }

  std::vector<CodecSample> samples() const override {
    Progress quiet;
    Params small;  // quick to train: tiny dictionaries and few iterations
    small.atoms = 16, small.sparsity = 4, small.iterations = 3, small.blockSide = 4;
    Params six = small;  // 11-bit pairs: pairs start inside bytes
    six.blockSide = 6, six.tolerance = 0.02, six.coefficientBits = 7;
    Params eight = small;
    eight.blockSide = 8, eight.atoms = 8, eight.sparsity = 3;
    std::vector<CodecSample> out;
    // 36^3 in 32-voxel bricks: two levels.
    out.push_back({"ksvd-ml36-float-m4",
                   ksvd::encode(generateMarschnerLobb(36, ScalarType::Float32), small, quiet)});
    out.push_back({"ksvd-sl13-int16-m6",
                   ksvd::encode(generateSheppLogan(13, ScalarType::Int16), six, quiet)});
    out.push_back({"ksvd-menger2-m8", ksvd::encode(generateMenger(2), eight, quiet)});
    return out;
  }

  std::vector<std::string> exampleOptions() const override {
    return {"--atoms", "32", "--sparsity", "4", "--iterations", "4"};
  }
};

}  // namespace

const Codec& KsvdCodecEntry::instance() {
  static const KsvdCodec codec;
  return codec;
}

}  // namespace voxwall::codec::ksvd
