// The tvq codec's registry entry: its compress and render options, report, info lines, render
// payload and samples.
#include <cmath>
#include <mutex>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/core/text.hpp>

namespace voxwall::codec::tvq {
namespace {

const char* const kLevelNames[kProgressiveLevels] = {"dc", "lp", "bp", "all"};
const char* const kLevelLabels[kProgressiveLevels] = {"mean", "+lowpass", "+bandpass", "all"};

class Payload final : public RenderPayload {
 public:
  Payload(const VolumeInfo& info, const SectionSet& sections, int partitions)
      : layout_(info, sections), partitions_(partitions) {}
  RangeGrid rangeGrid() const override { return layout_.rangeGrid(partitions_); }
  // Everything joined in one buffer, made when a device backend first asks (a CPU rank reads the
  // sections where they are mapped and makes a sub-volume's codebooks when its rays reach it).
  std::span<const std::byte> bytes() const override {
    std::call_once(joinOnce_, [this] { joined_ = layout_.joinedBytes(); });
    return joined_;
  }
  AnyView view(const std::byte* base) const override {
    return AnyView(layout_.view(base, partitions_));
  }
  void releaseDecodeTables() const override { layout_.releaseAssociated(); }

 private:
  Layout layout_;
  int partitions_;
  mutable std::once_flag joinOnce_;
  mutable std::vector<std::byte> joined_;
};

std::string psnrText(double v) {
  return std::isinf(v) ? std::string("exact") : formatLine("%.2f dB", v);
}

std::string encodeReport(const EncodeStats& s, const Volume& v, const Params& p) {
  std::string report = formatLine(
      "\n  %s, %llu blocks in %d sub-volume(s) of %d^3 voxels: %llu coded, %llu uncoded background",
      p.transform == Transform::Klt ? "KLT" : "DCT", (unsigned long long)s.blocks, s.subvolumes,
      p.subvolumeVoxels, (unsigned long long)s.coded, (unsigned long long)(s.blocks - s.coded));
  report += "\n  classes:";
  for (int c = 0; c < kClasses; ++c)
    if (s.classBlocks[std::size_t(c)])
      report += formatLine(" %s %.1f%%", className(c),
                           100.0 * double(s.classBlocks[std::size_t(c)]) / double(s.blocks));
  report += formatLine(
      "\n  %d code bits per coded block (mean %.1f lowpass, %.1f bandpass, %.1f highpass) + %d "
      "mean bits",
      s.codeBits, s.meanCodeBits[0], s.meanCodeBits[1], s.meanCodeBits[2], p.dcBits);
  report += formatLine("\n  codebooks %s, records %s, occupancy %s: %.3f bits per voxel",
                       humanBytes(double(s.codebookBytes)).c_str(),
                       humanBytes(double(s.recordBytes)).c_str(),
                       humanBytes(double(s.occupancyBytes)).c_str(),
                       bitsPerVoxel(s.codebookBytes + s.recordBytes + s.occupancyBytes, v));
  report += formatLine("\n  transform %.2fs, classify %.2fs, train (LBG) and code %.2fs",
                       s.transformSeconds, s.classifySeconds, s.trainSeconds);
  report += "\n  PSNR per progressive level:";
  for (int l = 0; l < kProgressiveLevels; ++l)
    report += formatLine(" %s %s", kLevelLabels[l], psnrText(s.levelPsnr[std::size_t(l)]).c_str());
  return report;
}

class TvqCodec final : public StreamingCodecOf<TvqCodecEntry> {
 public:
  std::string_view summary() const override {
    return "transform vector quantization of 4^3 blocks (Fout & Ma): KLT or DCT, classified "
           "partitioned VQ with associated codebooks, progressive levels; lossy, any scalar type";
  }

  std::vector<CodecOption> options() const override {
    return {
        {"--transform", "tvq codec: block transform, klt (learned from the volume) or dct", "klt"},
        {"--codebook-bits",
         "tvq codec: bits of the lowpass, bandpass and highpass codes together per coded block "
         "(0..39), split among them by a Lagrangian allocation",
         "20"},
        {"--bits-per-voxel",
         "tvq codec: instead, the Lagrangian allocation of code bits and codebook sizes (their "
         "storage counted) whose file fits this size",
         ""},
        {"--dc-bits", "tvq codec: bits of a block's quantized mean (1..16)", "8"},
        {"--subvolume",
         "tvq codec: sub-volume side in voxels (a multiple of 4, up to 1024), each with its own "
         "codebooks",
         "256"},
        {"--fidelity",
         "tvq codec: RMS error a block's class may leave by dropping zones, as a fraction of the "
         "value range",
         "0.005"},
        {"--no-classes",
         "tvq codec: one class for every coded block (all zones), to compare with classified VQ",
         "", true},
        {"--iterations", "tvq codec: LBG iterations after the last split", "10"}};
  }

  // Streams: a row of sub-volumes of the input in memory at a time.
  CompressedVolume encodeSource(const VolumeSource& volume, const CodecOptionValues& options,
                                Progress& progress, std::string& report) const override {
    Params p;
    const std::string transform = options.text("--transform", "klt");
    if (transform == "klt")
      p.transform = Transform::Klt;
    else if (transform == "dct")
      p.transform = Transform::Dct;
    else
      throw std::invalid_argument("--transform must be klt or dct, not '" + transform + "'");
    p.codeBits = options.integer("--codebook-bits", p.codeBits, 0, 3 * kMaxCodeBits);
    p.targetBitsPerVoxel = options.number("--bits-per-voxel", 0, 1e-9, 64);
    if (p.targetBitsPerVoxel > 0 && options.given("--codebook-bits"))
      throw std::invalid_argument("--codebook-bits and --bits-per-voxel exclude each other");
    p.dcBits = options.integer("--dc-bits", p.dcBits, 1, 16);
    p.subvolumeVoxels =
        options.integer("--subvolume", p.subvolumeVoxels, 4, 4 * kMaxSubvolumeBlocks);
    if (p.subvolumeVoxels % 4)
      throw std::invalid_argument("--subvolume must be a multiple of 4, not " +
                                  std::to_string(p.subvolumeVoxels));
    p.fidelity = options.number("--fidelity", p.fidelity, 0, 0.999);
    p.classified = !options.flag("--no-classes");
    p.iterations = options.integer("--iterations", p.iterations, 1, 1000);
    p.threads = options.threads;
    EncodeStats s;
    CompressedVolume out = tvq::encode(volume, p, progress, &s);
    report = encodeReport(s, volume.headerVolume(), p);
    return out;
  }

  Volume decode(const VolumeInfo& info, const SectionSet& sections) const override {
    return tvq::decode(info, sections);
  }

  InfoLines describe(const VolumeInfo& info, const SectionSet& sections) const override {
    const Layout layout(info, sections);
    InfoLines lines;
    lines.push_back(
        {"transform",
         formatLine("%s, 4^3 blocks, %s", layout.transform() == Transform::Klt ? "KLT" : "DCT",
                    layout.classified()
                        ? formatLine("classified (fidelity %g)", layout.fidelity()).c_str()
                        : "one class")});
    lines.push_back({"sub-volumes", formatLine("%d of %d^3 blocks; %llu coded blocks",
                                               layout.subvolumes(), layout.subvolumeBlocks(),
                                               (unsigned long long)layout.codedBlocks())});
    lines.push_back({"codebooks", formatLine("%llu lowpass, %llu bandpass, %llu highpass "
                                             "codevectors; %d code + %d mean bits per block",
                                             (unsigned long long)layout.codevectors(0),
                                             (unsigned long long)layout.codevectors(1),
                                             (unsigned long long)layout.codevectors(2),
                                             layout.codeBits(), layout.dcBits())});
    std::string levels;
    for (int l = 0; l < kProgressiveLevels; ++l)
      levels += formatLine("%s%s (%s) %s", l ? ", " : "", kLevelNames[l], kLevelLabels[l],
                           psnrText(layout.levelPsnr(l)).c_str());
    lines.push_back({"progressive", levels + " (render --progressive LEVEL)"});
    lines.push_back({"quality", std::isinf(layout.levelPsnr(kProgressiveLevels - 1))
                                    ? std::string("exact")
                                    : formatLine("lossy, PSNR %.2f dB",
                                                 layout.levelPsnr(kProgressiveLevels - 1))});
    return lines;
  }

  std::unique_ptr<RenderPayload> open(const VolumeInfo& info,
                                      const SectionSet& sections) const override {
    return std::make_unique<Payload>(info, sections, 3);
  }

  std::vector<CodecOption> renderOptions() const override {
    return {{"--progressive",
             "tvq files: render the progressive level LEVEL: dc (block means), lp (+ lowpass), "
             "bp (+ bandpass) or all",
             "all"}};
  }

  std::unique_ptr<RenderPayload> openWith(const VolumeInfo& info, const SectionSet& sections,
                                          const CodecOptionValues& o) const override {
    const std::string level = o.text("--progressive", "all");
    for (int l = 0; l < kProgressiveLevels; ++l)
      if (level == kLevelNames[l]) return std::make_unique<Payload>(info, sections, l);
    throw std::invalid_argument("--progressive must be dc, lp, bp or all, not '" + level + "'");
  }

  std::vector<CodecSample> samples() const override {
    Progress quiet;
    Params klt;  // quick: small codebooks, few iterations
    klt.codeBits = 9, klt.iterations = 3, klt.subvolumeVoxels = 16;
    Params dct = klt;
    dct.transform = Transform::Dct, dct.fidelity = 0.03, dct.subvolumeVoxels = 256;
    Params flat = klt;
    flat.classified = false, flat.dcBits = 6;
    std::vector<CodecSample> out;
    out.push_back({"tvq-ml24-float-klt",
                   tvq::encode(generateMarschnerLobb(24, ScalarType::Float32), klt, quiet)});
    out.push_back(
        {"tvq-sl14-int16-dct", tvq::encode(generateSheppLogan(14, ScalarType::Int16), dct, quiet)});
    out.push_back({"tvq-menger2-noclasses", tvq::encode(generateMenger(2), flat, quiet)});
    return out;
  }

  std::vector<std::string> exampleOptions() const override {
    return {"--codebook-bits", "12", "--iterations", "3"};
  }
};

}  // namespace

const Codec& TvqCodecEntry::instance() {
  static const TvqCodec codec;
  return codec;
}

}  // namespace voxwall::codec::tvq
