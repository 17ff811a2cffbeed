// The raw codec's registry entry: raw bricks (raw_bricks.hpp) stored as they are; its compress
// options, info lines, render payload and samples.
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/render_payload.hpp>

namespace voxwall::codec::raw {
namespace {

class RawCodec final : public CodecOf<RawCodecEntry> {
  static rawbricks::Params params(const CodecOptionValues& options) {
    const rawbricks::Params defaults;
    rawbricks::Params p;
    p.brickVoxels = options.integer("--brick", defaults.brickVoxels, 1, 1 << 20);
    p.rangeCellVoxels = options.integer("--range-cell", defaults.rangeCellVoxels, 1, 1 << 20);
    return p;
  }

 public:
  bool compresses() const override { return false; }

  std::string_view summary() const override {
    return "bricked, uncompressed (every scalar type; the reference the lossy codecs are measured "
           "against)";
  }

  std::vector<CodecOption> options() const override {
    const rawbricks::Params defaults;
    return {{"--brick",
             "raw codec: voxels per brick side (4, 8, 16, 32, 64); each brick is stored with a "
             "one-voxel apron, so 16 stores 1.2x the voxels and 8 stores 1.42x",
             std::to_string(defaults.brickVoxels)},
            {"--range-cell",
             "raw codec: voxels per side of the value-range cells used for empty-space skipping (2 "
             "to 64, power of two)",
             std::to_string(defaults.rangeCellVoxels)}};
  }

  CompressedVolume encode(const Volume& volume, const CodecOptionValues& options,
                          Progress& progress, std::string&) const override {
    return rawbricks::encode(volume, params(options), progress);
  }

  // Streams: one row of bricks in memory at a time.
  CompressedVolume encodeSource(const VolumeSource& source, const CodecOptionValues& options,
                                Progress& progress, std::string&) const override {
    return rawbricks::encode(source, params(options), progress);
  }

  Volume decode(const VolumeInfo& info, const SectionSet& sections) const override {
    return rawbricks::decode(info, sections);
  }

  InfoLines describe(const VolumeInfo& info, const SectionSet& sections) const override {
    const rawbricks::Layout layout(info, sections);
    const int b = 1 << layout.brickShift();
    const glm::ivec3 b3 = layout.bricks(), cells = layout.rangeCells();
    return {
        {"bricks", std::to_string(b3.x) + " x " + std::to_string(b3.y) + " x " +
                       std::to_string(b3.z) + " of " + std::to_string(b) + "^3 voxels (stored as " +
                       std::to_string(b + 1) + "^3 with their apron)"},
        {"ranges", std::to_string(cells.x) + " x " + std::to_string(cells.y) + " x " +
                       std::to_string(cells.z) + " cells of " +
                       std::to_string(layout.rangeCellVoxels()) + "^3 voxels"}};
  }

  std::unique_ptr<RenderPayload> open(const VolumeInfo& info,
                                      const SectionSet& sections) const override {
    return rawbricks::openPayload(info, sections);
  }

  std::vector<CodecSample> samples() const override {
    Progress quiet;
    std::vector<CodecSample> out;
    out.push_back({"raw-menger1", rawbricks::encode(generateMenger(1), {4}, quiet)});
    out.push_back({"raw-ml5-float",
                   rawbricks::encode(generateMarschnerLobb(5, ScalarType::Float32), {4}, quiet)});
    out.push_back(
        {"raw-sl6-int16", rawbricks::encode(generateSheppLogan(6, ScalarType::Int16), {8}, quiet)});
    return out;
  }

  std::vector<std::string> exampleOptions() const override { return {"--brick", "8"}; }
};

}  // namespace

const Codec& RawCodecEntry::instance() {
  static const RawCodec codec;
  return codec;
}

}  // namespace voxwall::codec::raw
