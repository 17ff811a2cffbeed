#include <algorithm>
#include <cstdio>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/codec/volume_io.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct DecompressOptions {
  std::string input, output;
  int step = -1;
  bool quiet = false;
};

void runDecompress(const DecompressOptions& o) {
  const auto file = codec::ContainerFile::open(o.input);
  const int steps = file.stepCount();
  if (o.step >= steps)
    throw std::invalid_argument("--step " + std::to_string(o.step) + ": " + o.input + " holds " +
                                std::to_string(steps) + " step(s), 0 to " +
                                std::to_string(steps - 1));
  if (o.step < 0 && steps > 1)
    throw std::invalid_argument(o.input + " holds " + std::to_string(steps) +
                                " steps: give --step K (0 to " + std::to_string(steps - 1) + ")");
  const int k = std::max(o.step, 0);
  codec::Volume v =
      codec::codecOf(file.info(), o.input).decode(file.stepInfo(k), file.stepSections(k));
  v.orientation = file.info().orientation;
  codec::writeVolume(v, o.output);
  if (o.quiet) return;
  std::printf("%s: %dx%dx%d %s\n", o.output.c_str(), v.dims.x, v.dims.y, v.dims.z,
              std::string(codec::scalarName(v.type)).c_str());
}

}  // namespace

void addDecompressCommand(CLI::App& app) {
  auto o = std::make_shared<DecompressOptions>();
  auto* cmd = app.add_subcommand("decompress", "Reconstruct the full volume of a .vwz file");
  cmd->add_option("input", o->input, "Input .vwz file")->required();
  cmd->add_option("-o,--output", o->output,
                  "Output, format from the extension: .raw (voxels in their own type, x fastest, "
                  "little-endian), .nrrd, .nhdr, .nii or .nii.gz")
      ->required();
  cmd->add_option("--step", o->step, "The step of a time series to write (from 0)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("-q,--quiet", o->quiet, "Print nothing but errors");
  cmd->callback([o] { runDecompress(*o); });
}

}  // namespace voxwall::cli
