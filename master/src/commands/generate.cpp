#include <cstdio>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/volume_io.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct GenerateOptions {
  std::string kind, output, type = "uint8";
  int size = 0, level = 4;
};

void runGenerate(const GenerateOptions& o) {
  const auto type = codec::parseScalarType(o.type);
  codec::Volume v;
  if (o.kind == "menger") {
    v = codec::generateMenger(o.level);
  } else if (o.kind == "marschner-lobb") {
    v = codec::generateMarschnerLobb(o.size ? o.size : 64, type);
  } else if (o.kind == "shepp-logan") {
    v = codec::generateSheppLogan(o.size ? o.size : 256, type);
  } else {
    throw std::invalid_argument("unknown volume '" + o.kind +
                                "' (expected menger, marschner-lobb or shepp-logan)");
  }
  if (codec::isContainerFile(o.output) || o.output.ends_with(".vwz")) {
    voxwall::Progress quiet;
    codec::writeContainer(codec::raw::encode(v, {}, quiet), o.output);
  } else {
    codec::writeVolume(v, o.output);
  }
  std::printf("%s: %dx%dx%d %s\n", o.output.c_str(), v.dims.x, v.dims.y, v.dims.z,
              std::string(codec::scalarName(v.type)).c_str());
}

}  // namespace

void addGenerateCommand(CLI::App& app) {
  auto o = std::make_shared<GenerateOptions>();
  auto* cmd = app.add_subcommand(
      "generate",
      "Write a synthetic volume: a Menger sponge (3^level voxels per side), the Marschner-Lobb "
      "test signal or a 3D Shepp-Logan head phantom");
  cmd->add_option("volume", o->kind, "menger, marschner-lobb or shepp-logan")->required();
  cmd->add_option("-o,--output", o->output,
                  "Output file: .nrrd, .nhdr, .raw, .nii, .nii.gz, or .vwz (raw codec)")
      ->required();
  cmd->add_option("--level", o->level, "Menger sponge level (0-7)")->capture_default_str();
  cmd->add_option("--size", o->size,
                  "Voxels per side for marschner-lobb (default 64) and shepp-logan (default 256)");
  cmd->add_option("--type", o->type,
                  "Scalar type for marschner-lobb and shepp-logan: uint8, "
                  "uint16, int16 or float32")
      ->capture_default_str();
  cmd->callback([o] { runGenerate(*o); });
}

}  // namespace voxwall::cli
