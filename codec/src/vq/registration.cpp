// The vq codec's registry entry: its compress options and report, info lines, render payload and
// samples.
#include <cmath>
#include <cstdio>
#include <mutex>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/core/text.hpp>

namespace voxwall::codec::vq {
namespace {

class Payload final : public RenderPayload {
 public:
  Payload(const VolumeInfo& info, const SectionSet& sections) : layout_(info, sections) {}
  RangeGrid rangeGrid() const override { return layout_.rangeGrid(); }
  // A series' step with the shared book: its data and the book joined, made when a device backend
  // first asks (a CPU rank reads both where they are mapped).
  std::span<const std::byte> bytes() const override {
    if (!layout_.sharedBook()) return layout_.dataBytes();
    std::call_once(joinOnce_, [this] { joined_ = layout_.joinedBytes(); });
    return joined_;
  }
  AnyView view(const std::byte* base) const override { return layout_.view(base); }

 private:
  Layout layout_;
  mutable std::once_flag joinOnce_;
  mutable std::vector<std::byte> joined_;
};

std::string encodeReport(const Params& p, const EncodeStats& s) {
  std::string report =
      formatLine("\n  %llu bricks, %llu unique, %llu codewords (%s, %s)",
                 (unsigned long long)s.bricks, (unsigned long long)s.uniqueBricks,
                 (unsigned long long)s.codewords, p.compressedCodebook ? "RBUC" : "plain",
                 !p.compressedCodebook ? "indices"
                 : s.indirect          ? "indirect mapping"
                                       : "direct mapping");
  report += formatLine("\n  offset volume %s, index table %s, codebook %s",
                       humanBytes(double(s.offsetVolumeBytes)).c_str(),
                       humanBytes(double(s.indexTableBytes)).c_str(),
                       humanBytes(double(s.codebookBytes)).c_str());
  if (p.compressedCodebook)
    report +=
        formatLine("; codewords by predictor: none %llu, x %llu, xy %llu, xyz %llu, raw %llu",
                   (unsigned long long)s.transformUse[0], (unsigned long long)s.transformUse[1],
                   (unsigned long long)s.transformUse[2], (unsigned long long)s.transformUse[3],
                   (unsigned long long)s.escapes);
  if (s.codewords == s.uniqueBricks && s.reduction <= 1) return report + "\n  lossless";
  const double plain = double(s.plainEquivalent);
  return report + formatLine(
                      "\n  lossy: 1/%d of the unique bricks, PSNR %.2f dB; k-means %d iterations "
                      "in %.2fs: %.3g distances computed, %.3g skipped by the norm bound, %.0fx "
                      "fewer than plain Lloyd",
                      s.reduction, s.psnr, s.iterations, s.kmeansSeconds,
                      double(s.distancesComputed), double(s.distancesSkipped),
                      s.distancesComputed ? plain / double(s.distancesComputed) : 0.0);
}

}  // namespace

namespace {

class VqCodec final : public StreamingCodecOf<VqCodecEntry> {
 public:
  std::string_view summary() const override {
    return "4^3 bricks deduplicated into a codebook (Guthe & Goesele), lossless unless --reduction "
           "or --bits-per-voxel; 8/12/16-bit integer data";
  }

  std::vector<CodecOption> options() const override {
    return {
        {"--reduction",
         "vq codec: keep 1/K of the unique bricks (k-means; K = 2, 4, ... 1024); 1 is lossless",
         "1"},
        {"--bits-per-voxel",
         "vq codec: choose the reduction for this size instead (bits per voxel of the coded "
         "data; lossless when that already fits)",
         ""},
        {"--codebook",
         "vq codec: 'compressed' (RBUC variable-length codewords) or 'plain' (bit-packed at the "
         "data's bit depth: faster to decode, larger)",
         "compressed"}};
  }

  // Streams: a row of bricks in memory at a time, besides the unique bricks.
  CompressedVolume encodeSource(const VolumeSource& source, const CodecOptionValues& options,
                                Progress& progress, std::string& report) const override {
    const Params p = paramsOf(options);
    EncodeStats s;
    CompressedVolume out = vq::encode(source, p, progress, &s);
    report = encodeReport(p, s);
    return out;
  }

  // One codebook for every step (the unique bricks of all steps, or k-means over them), stored
  // once: the bricks a series keeps from step to step are coded once.
  CompressedSeries encodeSeries(const SeriesSource& series, const CodecOptionValues& options,
                                Progress& progress, std::string& report) const override {
    if (options.stepsAlone || series.steps() == 1)
      return Codec::encodeSeries(series, options, progress, report);
    const Params p = paramsOf(options);
    std::vector<EncodeStats> s;
    CompressedSeries out = vq::encodeSeries(series, p, progress, &s);
    report = encodeReport(p, s.front());
    report += formatLine(
        "\n  one codebook of %llu codewords for every step, stored once (--steps-alone: a "
        "codebook a step)",
        (unsigned long long)s.front().codewords);
    // Lossless, one codebook gains only where steps repeat bricks exactly, and its offset
    // entries are wider: both are coded (fast, streaming) and the smaller kept.
    if (p.reduction == 1 && p.targetBitsPerVoxel == 0) {
      std::string aloneReport;
      CompressedSeries alone = Codec::encodeSeries(series, options, progress, aloneReport);
      if (alone.payloadBytes() < out.payloadBytes()) {
        report = aloneReport + formatLine(
                                   "\n  a codebook a step: %llu bytes, smaller than one codebook "
                                   "for every step (%llu bytes)",
                                   (unsigned long long)alone.payloadBytes(),
                                   (unsigned long long)out.payloadBytes());
        return alone;
      }
    }
    return out;
  }

 private:
  static Params paramsOf(const CodecOptionValues& options) {
    Params p;
    p.reduction = options.integer("--reduction", 1, 1, 1 << 20);
    p.targetBitsPerVoxel = options.number("--bits-per-voxel", 0, 1e-9, 64);
    const std::string codebook = options.text("--codebook", "compressed");
    if (codebook != "compressed" && codebook != "plain")
      throw std::invalid_argument("--codebook must be 'compressed' or 'plain', not '" + codebook +
                                  "'");
    if (options.given("--reduction") && options.given("--bits-per-voxel"))
      throw std::invalid_argument("give --reduction or --bits-per-voxel, not both");
    p.compressedCodebook = codebook == "compressed";
    p.threads = options.threads;
    return p;
  }

 public:
  Volume decode(const VolumeInfo& info, const SectionSet& sections) const override {
    return vq::decode(info, sections);
  }

  InfoLines describe(const VolumeInfo& info, const SectionSet& sections) const override {
    const Layout layout(info, sections);
    const glm::ivec3 b3 = (info.dims + 3) / 4;
    const bool compressed = layout.flags() & kCompressed;
    InfoLines lines;
    lines.push_back(
        {"bricks", formatLine("%d x %d x %d of 4^3 voxels, %llu codewords of %d-bit values", b3.x,
                              b3.y, b3.z, (unsigned long long)layout.codewords(), layout.bits())});
    lines.push_back(
        {"codebook",
         formatLine("%s, %s%s (%s)", compressed ? "RBUC-compressed" : "plain bit-packed",
                    humanBytes(double(layout.codebookBytes())).c_str(),
                    layout.sharedBook() ? ", one for every step" : "",
                    !compressed                    ? "offset volume holds indices"
                    : (layout.flags() & kIndirect) ? "indirect mapping: index table"
                                                   : "direct mapping: byte addresses")});
    if (layout.reduction() > 1 || !std::isinf(layout.psnr()))
      lines.push_back({"quality", formatLine("lossy, 1/%d of the unique bricks, PSNR %.2f dB",
                                             layout.reduction(), layout.psnr())});
    else
      lines.push_back({"quality", "lossless"});
    return lines;
  }

  std::unique_ptr<RenderPayload> open(const VolumeInfo& info,
                                      const SectionSet& sections) const override {
    return std::make_unique<Payload>(info, sections);
  }

  std::vector<CodecSample> samples() const override {
    Progress quiet;
    Params lossy;
    lossy.reduction = 2;
    Params plain;
    plain.compressedCodebook = false;
    std::vector<CodecSample> out;
    out.push_back(
        {"vq-sl7-int16", vq::encode(generateSheppLogan(7, ScalarType::Int16), {}, quiet)});
    out.push_back({"vq-ml9-lossy", vq::encode(generateMarschnerLobb(9), lossy, quiet)});
    out.push_back({"vq-menger2-plain", vq::encode(generateMenger(2), plain, quiet)});
    return out;
  }

  std::vector<std::string> exampleOptions() const override { return {"--reduction", "4"}; }
};

}  // namespace

const Codec& VqCodecEntry::instance() {
  static const VqCodec codec;
  return codec;
}

}  // namespace voxwall::codec::vq
