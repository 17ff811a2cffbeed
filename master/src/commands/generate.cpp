#include <cstdio>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/codec/volume_io.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct GenerateOptions {
  std::string kind, output, type = "uint8";
  int size = 0, level = 4, steps = 1;
  bool quiet = false;
};

// A time-varying volume of o.steps steps: a 4D NIfTI file, a file per step (a %d pattern) or a
// .vwz series (raw codec).
void generateSeries(const GenerateOptions& o, codec::ScalarType type) {
  const int n = o.size ? o.size : 64;
  const bool container = o.output.ends_with(".vwz");
  const bool nifti = o.output.ends_with(".nii") || o.output.ends_with(".nii.gz");
  const bool pattern = codec::isStepPattern(o.output);
  if (!container && !nifti && !pattern)
    throw std::invalid_argument(
        "--steps writes a .vwz series, a 4D .nii/.nii.gz, or one file a step through a %d "
        "pattern (e.g. blobs_%03d.nrrd); " +
        o.output + " is none of them");
  std::vector<codec::Volume> volumes;
  std::vector<codec::CompressedVolume> coded;
  voxwall::Progress quiet;
  for (int k = 0; k < o.steps; ++k) {
    codec::Volume v = codec::generateOrbitingBlobs(n, k, o.steps, type);
    if (container) {
      coded.push_back(codec::rawbricks::encode(v, {}, quiet));
    } else if (pattern) {
      char name[4096];
      std::snprintf(name, sizeof name, o.output.c_str(), k);
      codec::writeVolume(v, name);
    } else {
      volumes.push_back(std::move(v));
    }
  }
  if (container) codec::writeContainer(codec::makeSeries(std::move(coded)), o.output);
  if (nifti) codec::writeNiftiSeries(volumes, o.output);
  if (!o.quiet)
    std::printf("%s: %d steps of %dx%dx%d %s\n", o.output.c_str(), o.steps, n, n, n,
                std::string(codec::scalarName(type)).c_str());
}

void runGenerate(const GenerateOptions& o) {
  const auto type = codec::parseScalarType(o.type);
  // One step of blobs goes wherever a volume can (a series' pattern or 4D file too).
  const bool series =
      o.output.ends_with(".nii") || o.output.ends_with(".nii.gz") || codec::isStepPattern(o.output);
  if (o.kind == "blobs" && (o.steps > 1 || series)) return generateSeries(o, type);
  if (o.steps != 1)
    throw std::invalid_argument("--steps needs a time-varying volume (blobs), not " + o.kind);
  codec::Volume v;
  if (o.kind == "menger") {
    v = codec::generateMenger(o.level);
  } else if (o.kind == "marschner-lobb") {
    v = codec::generateMarschnerLobb(o.size ? o.size : 64, type);
  } else if (o.kind == "shepp-logan") {
    v = codec::generateSheppLogan(o.size ? o.size : 256, type);
  } else if (o.kind == "blobs") {
    v = codec::generateOrbitingBlobs(o.size ? o.size : 64, 0, 1, type);
  } else {
    throw std::invalid_argument("unknown volume '" + o.kind +
                                "' (expected menger, marschner-lobb, shepp-logan or blobs)");
  }
  if (codec::isContainerFile(o.output) || o.output.ends_with(".vwz")) {
    voxwall::Progress quiet;
    codec::writeContainer(codec::rawbricks::encode(v, {}, quiet), o.output);
  } else {
    codec::writeVolume(v, o.output);
  }
  if (!o.quiet)
    std::printf("%s: %dx%dx%d %s\n", o.output.c_str(), v.dims.x, v.dims.y, v.dims.z,
                std::string(codec::scalarName(v.type)).c_str());
}

}  // namespace

void addGenerateCommand(CLI::App& app) {
  auto o = std::make_shared<GenerateOptions>();
  auto* cmd = app.add_subcommand(
      "generate",
      "Write a synthetic volume: a Menger sponge (3^level voxels per side), the Marschner-Lobb "
      "test signal, a 3D Shepp-Logan head phantom, or a time series of orbiting, growing blobs "
      "beside a still torus");
  cmd->add_option("volume", o->kind, "menger, marschner-lobb, shepp-logan or blobs")->required();
  cmd->add_option("-o,--output", o->output,
                  "Output file: .nrrd, .nhdr, .raw, .nii, .nii.gz, or .vwz (raw codec); for a "
                  "series a .vwz, a 4D .nii/.nii.gz, or a %d pattern (one file a step)")
      ->required();
  cmd->add_option("--steps", o->steps, "Time steps of blobs")
      ->check(CLI::Range(1, int(codec::kMaxSteps)))
      ->capture_default_str();
  cmd->add_option("--level", o->level, "Menger sponge level (0-7)")->capture_default_str();
  cmd->add_option(
      "--size", o->size,
      "Voxels per side for marschner-lobb and blobs (default 64) and shepp-logan (default 256)");
  cmd->add_option("--type", o->type,
                  "Scalar type for marschner-lobb, shepp-logan and blobs: uint8, "
                  "uint16, int16 or float32")
      ->capture_default_str();
  cmd->add_flag("-q,--quiet", o->quiet, "Print nothing but errors");
  cmd->callback([o] { runGenerate(*o); });
}

}  // namespace voxwall::cli
