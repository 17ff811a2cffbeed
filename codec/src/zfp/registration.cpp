// The zfp codec's registry entry: its compress options and report, info lines, render payload
// and samples.
#include <cmath>
#include <mutex>
#include <optional>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/zfp_codec.hpp>
#include <voxwall/core/text.hpp>

namespace voxwall::codec::zfp {
namespace {

// The host samples the compressed bricks (ZfpView). libzfp decodes on the host only, so a device
// backend samples the volume decoded once, as raw bricks: bytes() builds them on its first call
// (only a device backend calls it) and deviceView() hands out their view over the device copy.
class Payload final : public RenderPayload {
 public:
  Payload(const VolumeInfo& info, const SectionSet& sections)
      : info_(info), sections_(sections), layout_(info, sections) {}
  RangeGrid rangeGrid() const override { return layout_.rangeGrid(); }
  std::span<const std::byte> bytes() const override {
    std::call_once(decodedOnce_,
                   [&] { decoded_.emplace(zfp::decode(info_, sections_), sections_.source); });
    return decoded_->layout().brickBytes();
  }
  AnyView view(const std::byte*) const override { return layout_.view(); }
  AnyView deviceView(const std::byte* base, std::span<const DeviceArray>) const override {
    bytes();
    return dispatchScalar(
        info_.type, [&](auto t) -> AnyView { return decoded_->layout().view<decltype(t)>(base); });
  }

 private:
  VolumeInfo info_;
  SectionSet sections_;
  Layout layout_;
  mutable std::once_flag decodedOnce_;
  mutable std::optional<rawbricks::DecodedBricks> decoded_;
};

std::string settingText(Mode mode, double setting) {
  switch (mode) {
    case Mode::Accuracy:
      return formatLine("tolerance %.4g", setting);
    case Mode::Precision:
      return formatLine("%d bit planes", int(setting));
    case Mode::Rate:
      return formatLine("%.4g bits per voxel per block", setting);
    case Mode::Reversible:
      return "bit for bit";
  }
  return "";
}

std::string encodeReport(const Params& p, const EncodeStats& s) {
  std::string report =
      formatLine("\n  %s, %s; %llu bricks of 16^3, %llu stored as they are",
                 std::string(modeName(s.mode)).c_str(), settingText(s.mode, s.setting).c_str(),
                 (unsigned long long)s.bricks, (unsigned long long)s.storedBricks);
  report += formatLine("\n  %.3f bits per voxel (stream %s, index %s)", s.bitsPerVoxel,
                       humanBytes(double(s.streamBytes)).c_str(),
                       humanBytes(double(s.indexBytes)).c_str());
  if (p.targetBitsPerVoxel > 0)
    report += formatLine(
        "\n  asked for %.3g bits per voxel: %s found in %d encodings of a sample of bricks "
        "(zfp's tolerances are powers of two, so a file can land well under the target)",
        p.targetBitsPerVoxel,
        s.mode == Mode::Reversible ? "the lossless file fits" : "the tolerance", s.searchSteps);
  if (std::isinf(s.psnr)) return report + "\n  lossless: every voxel decodes to its value";
  return report + formatLine("\n  PSNR %.2f dB, largest error %.4g", s.psnr, s.maxError);
}

class ZfpCodec final : public StreamingCodecOf<ZfpCodecEntry> {
 public:
  std::string_view summary() const override {
    return "16^3 bricks each compressed by the zfp library (fixed accuracy by default, fixed "
           "precision, fixed rate or lossless) with an index for random access; every scalar "
           "type";
  }

  std::vector<CodecOption> options() const override {
    return {
        {"--tolerance",
         "zfp codec: fixed accuracy (its default mode): no voxel off by more than this, in "
         "the data's units (zfp rounds it down to a power of two; default: the value range / "
         "64)",
         ""},
        {"--precision", "zfp codec: fixed precision: bit planes kept per 4^3 block (1..32)", ""},
        {"--rate",
         "zfp codec: fixed rate: bits per voxel of every 4^3 block (0.25..32; the same size "
         "everywhere, the lowest quality per bit)",
         ""},
        {"--bits-per-voxel",
         "zfp codec: fixed accuracy with the smallest tolerance whose file (index included) "
         "fits this size, or lossless when that fits",
         ""},
        {"--lossless", "zfp codec: zfp's reversible mode: every voxel decodes to its value", "",
         true}};
  }

  // Streams: a row of bricks (16 slices) in memory at a time, besides the coded data.
  CompressedVolume encodeSource(const VolumeSource& source, const CodecOptionValues& options,
                                Progress& progress, std::string& report) const override {
    const char* modes[] = {"--tolerance", "--precision", "--rate", "--bits-per-voxel",
                           "--lossless"};
    int given = 0;
    for (const char* m : modes) given += options.given(m) ? 1 : 0;
    if (given > 1)
      throw std::invalid_argument(
          "give one of --tolerance, --precision, --rate, --bits-per-voxel and --lossless");
    Params p;
    p.tolerance = options.number("--tolerance", 0, 1e-300, 1e300);
    p.precision = options.integer("--precision", 16, 1, 32);
    p.rate = options.number("--rate", 4, 0.25, 32);
    p.targetBitsPerVoxel = options.number("--bits-per-voxel", 0, 1e-3, 64);
    p.mode = options.given("--precision") ? Mode::Precision
             : options.given("--rate")    ? Mode::Rate
             : options.flag("--lossless") ? Mode::Reversible
                                          : Mode::Accuracy;
    p.threads = options.threads;
    EncodeStats s;
    CompressedVolume out = zfp::encode(source, p, progress, &s);
    report = encodeReport(p, s);
    return out;
  }

  Volume decode(const VolumeInfo& info, const SectionSet& sections) const override {
    return zfp::decode(info, sections);
  }

  InfoLines describe(const VolumeInfo& info, const SectionSet& sections) const override {
    const Layout layout(info, sections);
    const glm::ivec3 b = (info.dims + 15) / 16;
    InfoLines lines;
    lines.push_back({"mode", std::string(modeName(layout.mode())) + ", " +
                                 settingText(layout.mode(), layout.setting())});
    lines.push_back(
        {"bricks", formatLine("%d x %d x %d of 16^3 voxels, %llu stored as they are", b.x, b.y, b.z,
                              (unsigned long long)layout.storedBricks())});
    lines.push_back({"stream", humanBytes(double(layout.streamBytes()))});
    if (std::isinf(layout.psnr()))
      lines.push_back({"quality", "lossless"});
    else
      lines.push_back({"quality", formatLine("PSNR %.2f dB, largest error %.4g", layout.psnr(),
                                             layout.maxError())});
    return lines;
  }

  std::unique_ptr<RenderPayload> open(const VolumeInfo& info,
                                      const SectionSet& sections) const override {
    return std::make_unique<Payload>(info, sections);
  }

  std::vector<CodecSample> samples() const override {
    Progress quiet;
    Params precision;
    precision.mode = Mode::Precision, precision.precision = 12;
    Params rate;
    rate.mode = Mode::Rate, rate.rate = 6;
    Params lossless;
    lossless.mode = Mode::Reversible;
    std::vector<CodecSample> out;
    out.push_back(
        {"zfp-ml20-float", zfp::encode(generateMarschnerLobb(20, ScalarType::Float32), {}, quiet)});
    out.push_back({"zfp-sl18-int16-precision",
                   zfp::encode(generateSheppLogan(18, ScalarType::Int16), precision, quiet)});
    out.push_back({"zfp-menger2-rate", zfp::encode(generateMenger(2), rate, quiet)});
    out.push_back({"zfp-ml9-uint16-lossless",
                   zfp::encode(generateMarschnerLobb(9, ScalarType::UInt16), lossless, quiet)});
    return out;
  }

  std::vector<std::string> exampleOptions() const override { return {"--tolerance", "2"}; }
};

}  // namespace

const Codec& ZfpCodecEntry::instance() {
  static const ZfpCodec codec;
  return codec;
}

}  // namespace voxwall::codec::zfp
