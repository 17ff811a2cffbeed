// The svmm codec's registry entry: its compress options and report, info lines, render payload
// (with the block pools a device backend builds, thesis section 3.3) and samples.
#include <bit>
#include <cmath>
#include <cstdio>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/text.hpp>

namespace voxwall::codec::svmm {
namespace {

// Block pools: every level but the root (and a block-compressed base) as a 3D array of blocks,
// which a device backend reads through a texture (or linear memory past the texture limits).
class Payload final : public RenderPayload {
 public:
  Payload(const VolumeInfo& info, const SectionSet& sections) : layout_(info, sections) {
    if (layout_.format() == kernels::kSvmmRgba32)
      throw FormatError(sections.source,
                        "an RGBA svmm volume cannot be rendered: the raycaster maps scalar values "
                        "through a transfer function");
  }
  RangeGrid rangeGrid() const override { return layout_.rangeGrid(); }
  std::span<const std::byte> bytes() const override { return layout_.dataBytes(); }
  AnyView view(const std::byte* base) const override { return layout_.view(base); }

  std::vector<DeviceArraySpec> deviceArrays() const override {
    std::vector<DeviceArraySpec> arrays;
    for (int L = 0; L < layout_.levels(); ++L) {
      if (!layout_.poolable(L)) continue;
      const auto shape = layout_.poolShape(L);
      const int wl = std::countr_zero(unsigned(layout_.widths()[std::size_t(L)]));
      DeviceArraySpec a;
      a.bytes = layout_.poolBytes(L);
      a.elementBytes = layout_.elementBytes(L);
      a.width = std::size_t(1) << (shape.uLog2 + wl);
      a.height = std::size_t(1) << (shape.vLog2 + wl);
      a.depth = std::size_t(shape.w) << wl;
      arrays.push_back(std::move(a));
    }
    return arrays;
  }

  AnyView deviceView(const std::byte* base, std::span<const DeviceArray> arrays) const override {
    kernels::SvmmView v = layout_.view(base);
    std::size_t next = 0;
    for (int L = 0; L < layout_.levels(); ++L) {
      if (!layout_.poolable(L)) continue;
      if (next >= arrays.size()) throw std::logic_error("svmm: fewer device arrays than pools");
      const auto shape = layout_.poolShape(L);
      kernels::SvmmLevel& level = v.level[L];
      level.pool = arrays[next].linear;
      level.texture = arrays[next].texture;
      level.poolULog2 = shape.uLog2, level.poolVLog2 = shape.vLog2;
      ++next;
    }
    return v;
  }

 private:
  Layout layout_;
};

// "4, 4, root" and "1200, 40, 1": block widths and blocks per level, from the base.
std::pair<std::string, std::string> levelLists(int levels, const std::vector<int>& widths,
                                               const std::vector<std::uint64_t>& blocks) {
  std::string w, b;
  for (int i = 0; i < levels; ++i) {
    const std::string sep = i ? ", " : "";
    w += sep + (i + 1 < levels ? std::to_string(widths[std::size_t(i)]) : std::string("root"));
    b += sep + std::to_string(blocks[std::size_t(i)]);
  }
  return {w, b};
}

}  // namespace

namespace {

class SvmmCodec final : public StreamingCodecOf<SvmmCodecEntry> {
 public:
  std::string_view summary() const override {
    return "sparse voxel mip-map (Faas): blocks within --quality of their mean dropped, lossless "
           "at "
           "quality 100; 8/16-bit integer data";
  }

  std::vector<CodecOption> options() const override {
    return {{"--quality",
             "svmm codec: 0..100; a block is dropped when every voxel is within sqrt(channels) x "
             "(1 - Q/100) x the value range of the block's mean; 100 is lossless",
             "100"},
            {"--block-width",
             "svmm codec: block width of every level (2, 4, ... 64) or 'stepped' (2, 4, 8, ... "
             "from the base level up)",
             "4"},
            {"--root-width", "svmm codec: stop building levels once a level is at most this wide",
             "32"},
            {"--base-compression",
             "svmm codec: store base blocks as 2^3 groups of an occupancy bitmap and one shared "
             "value (lossy; the thesis's Fig. 1.2c)",
             "", true}};
  }

  // Streams: level 1 from windows of slices, the base level from slabs of 2 w0 slices.
  CompressedVolume encodeSource(const VolumeSource& source, const CodecOptionValues& options,
                                Progress& progress, std::string& report) const override {
    Params p;
    p.quality = options.integer("--quality", p.quality, 0, 100);
    p.rootWidth = options.integer("--root-width", p.rootWidth, 2, 1 << 20);
    p.baseCompression = options.flag("--base-compression");
    p.threads = options.threads;
    const std::string width = options.text("--block-width", "4");
    if (width == "stepped") {
      p.stepped = true;
    } else {
      const int w = options.integer("--block-width", 4, 2, 64);
      if (w & (w - 1))
        throw std::invalid_argument(
            "--block-width must be a power of two in 2..64 or 'stepped', not '" + width + "'");
      p.blockWidth = w;
    }
    EncodeStats s;
    CompressedVolume out = svmm::encode(source, p, progress, &s);
    const auto [widths, blocks] = levelLists(s.levels, s.widths, s.blocks);
    report = formatLine(
        "\n  %d levels (block widths %s; blocks per level from the base: %s)%s"
        "\n  quality %d (delta %.4g of the value range): ",
        s.levels, widths.c_str(), blocks.c_str(),
        p.baseCompression && s.levels > 1 ? ", base blocks compressed" : "", p.quality, s.delta);
    report += std::isinf(s.psnr) ? std::string("lossless") : formatLine("PSNR %.2f dB", s.psnr);
    return out;
  }

  Volume decode(const VolumeInfo& info, const SectionSet& sections) const override {
    return svmm::decode(info, sections);
  }

  void verify(const VolumeInfo& info, const SectionSet& sections) const override {
    const Layout layout(info, sections);
    (void)layout.rangeGrid();
    if (layout.format() == kernels::kSvmmRgba32)
      (void)decodeRgba(info, sections);
    else
      (void)svmm::decode(info, sections);
  }

  InfoLines describe(const VolumeInfo& info, const SectionSet& sections) const override {
    const Layout layout(info, sections);
    static const char* kFormats[] = {"", "DENSITY8", "DENSITY16", "RGBA32"};
    const auto [widths, blocks] = levelLists(layout.levels(), layout.widths(), layout.blocks());
    InfoLines lines;
    lines.push_back({"voxels", std::string(kFormats[layout.format()]) +
                                   ((layout.flags() & kBlockCompressed) && layout.levels() > 1
                                        ? ", base blocks compressed (bitmap + one value per 2^3)"
                                        : "")});
    lines.push_back({"levels", formatLine("%d (block widths %s%s; root width %d)", layout.levels(),
                                          widths.c_str(), layout.stepped() ? ", stepped" : "",
                                          layout.rootWidth())});
    lines.push_back({"blocks", blocks + " (per level, from the base)"});
    if (std::isinf(layout.psnr()))
      lines.push_back({"quality", formatLine("%d, lossless", layout.quality())});
    else
      lines.push_back({"quality", formatLine("%d (delta %.4g), PSNR %.2f dB", layout.quality(),
                                             layout.delta(), layout.psnr())});
    return lines;
  }

  std::unique_ptr<RenderPayload> open(const VolumeInfo& info,
                                      const SectionSet& sections) const override {
    return std::make_unique<Payload>(info, sections);
  }

  std::vector<CodecSample> samples() const override {
    Progress quiet;
    Params tree;
    tree.blockWidth = 2, tree.rootWidth = 2;
    Params stepped;
    stepped.stepped = true, stepped.rootWidth = 4, stepped.quality = 80,
    stepped.baseCompression = true;
    std::vector<CodecSample> out;
    out.push_back({"svmm-sl9-tree", svmm::encode(generateSheppLogan(9), tree, quiet)});
    out.push_back({"svmm-sl11-int16-stepped",
                   svmm::encode(generateSheppLogan(11, ScalarType::Int16), stepped, quiet)});
    out.push_back({"svmm-menger2-rgba", encodeRgba(generateMengerRgba(2), tree, quiet)});
    return out;
  }

  std::vector<std::string> exampleOptions() const override {
    return {"--quality", "90", "--block-width", "stepped", "--root-width", "8"};
  }
};

}  // namespace

const Codec& SvmmCodecEntry::instance() {
  static const SvmmCodec codec;
  return codec;
}

}  // namespace voxwall::codec::svmm
