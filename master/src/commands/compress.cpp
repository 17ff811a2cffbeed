#include <chrono>
#include <cstdio>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/raw_codec.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct CompressOptions {
  std::string input, output, codec = "raw";
  int brick = codec::raw::Params{}.brickVoxels;
  int rangeCell = codec::raw::Params{}.rangeCellVoxels;
  bool quiet = false;
  RawInputOptions raw;
};

void runCompress(const CompressOptions& o) {
  const auto codecId = codec::parseCodecName(o.codec);
  if (codecId != codec::CodecId::Raw)
    throw std::invalid_argument("codec '" + o.codec + "' is not implemented yet (available: raw)");
  const auto start = std::chrono::steady_clock::now();
  codec::Volume v = loadVolume(o.input, o.raw.layout());
  if (!o.raw.spacing.empty()) v.spacing = parseSpacing(o.raw.spacing, "--spacing");
  codec::Progress progress = makeProgress(o.quiet);
  const auto compressed = codec::raw::encode(v, {o.brick, o.rangeCell}, progress);
  const std::uint64_t fileBytes = codec::writeContainer(compressed, o.output);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s: %dx%dx%d %s, codec %s, %s, %.3f bits/voxel, %.2fs\n", o.output.c_str(), v.dims.x,
              v.dims.y, v.dims.z, std::string(codec::scalarName(v.type)).c_str(), o.codec.c_str(),
              humanBytes(double(fileBytes)).c_str(), codec::bitsPerVoxel(fileBytes, v), seconds);
}

}  // namespace

void addCompressCommand(CLI::App& app) {
  auto o = std::make_shared<CompressOptions>();
  auto* cmd = app.add_subcommand("compress", "Compress a volume file into a .vwz container");
  cmd->add_option("input", o->input,
                  "Volume: .nii/.nii.gz, .nrrd/.nhdr, .raw (with --dims/--type), .tif/.tiff, a "
                  "directory of slices, or generated:KIND:SIZE")
      ->required();
  cmd->add_option("-o,--output", o->output, "Output .vwz file")->required();
  cmd->add_option("--codec", o->codec, "Codec (only 'raw' so far: bricked, uncompressed)")
      ->capture_default_str();
  cmd->add_option(
         "--brick", o->brick,
         "raw codec: voxels per brick side (4, 8, 16, 32, 64); each brick is stored with a "
         "one-voxel apron, so 16 stores 1.2x the voxels and 8 stores 1.42x")
      ->capture_default_str();
  cmd->add_option("--range-cell", o->rangeCell,
                  "raw codec: voxels per side of the value-range cells used for empty-space "
                  "skipping (2 to 64, power of two)")
      ->capture_default_str();
  cmd->add_flag("-q,--quiet", o->quiet, "No progress output");
  o->raw.addTo(*cmd);
  cmd->callback([o] { runCompress(*o); });
}

}  // namespace voxwall::cli
