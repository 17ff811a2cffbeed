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
};

void runDecompress(const DecompressOptions& o) {
  const auto file = codec::ContainerFile::open(o.input);
  codec::Volume v = codec::codecOf(file.info(), o.input).decode(file.info(), file.sections());
  v.orientation = file.info().orientation;
  codec::writeVolume(v, o.output);
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
  cmd->callback([o] { runDecompress(*o); });
}

}  // namespace voxwall::cli
