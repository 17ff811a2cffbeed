#include <cstdio>
#include <filesystem>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/core/text.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct InfoOptions {
  std::string input;
  RawInputOptions raw;
};

void printVolumeLines(glm::ivec3 dims, codec::ScalarType type, glm::dvec3 spacing,
                      const codec::Orientation& orientation, double lo, double hi) {
  std::printf("dims        %d x %d x %d (%zu voxels)\n", dims.x, dims.y, dims.z,
              std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z));
  std::printf("type        %s\n", std::string(codec::scalarName(type)).c_str());
  std::printf("spacing     %g x %g x %g\n", spacing.x, spacing.y, spacing.z);
  const glm::dmat3& d = orientation.direction;
  std::printf("orientation %s (the patient directions of the x, y and z axes)\n",
              codec::orientationLetters(d).c_str());
  // The voxel-to-patient matrix (LPS, millimetres), row by row: index (i, j, k, 1) to x, y, z
  // (+ 0.0 prints -0 as 0).
  std::printf("to patient  LPS mm = M * (i, j, k, 1), M =\n");
  for (int r = 0; r < 3; ++r)
    std::printf("            %10.4f %10.4f %10.4f %12.4f\n", d[0][r] * spacing.x + 0.0,
                d[1][r] * spacing.y + 0.0, d[2][r] * spacing.z + 0.0, orientation.origin[r] + 0.0);
  std::printf("values      %g .. %g\n", lo, hi);
}

// What the codec says of a .vwz file's step 0, and of each step of a series.
void printCodecLines(const codec::ContainerFile& file, const codec::Codec& c) {
  const auto& info = file.info();
  if (info.steps > 1)
    std::printf("shared      %s used by every step; step 0:\n",
                humanBytes(double(file.sharedBytes())).c_str());
  for (const auto& [label, text] : c.describe(file.stepInfo(0), file.sections()))
    std::printf("%-12s%s\n", label.c_str(), text.c_str());
  // Each step: its own bytes, its values and its quality (the codec's "quality" line).
  for (int k = 0; k < info.steps && info.steps > 1; ++k) {
    const codec::VolumeInfo step = file.stepInfo(k);
    std::string quality = "lossless";
    for (const auto& [label, text] : c.describe(step, file.stepSections(k)))
      if (label == "quality") quality = text;
    std::printf("step %-7d%s, %.3f bits/voxel, values %g .. %g, %s\n", k,
                humanBytes(double(file.stepBytes(k))).c_str(),
                8.0 * double(file.stepBytes(k)) / double(info.voxelCount()), step.valueMin,
                step.valueMax, quality.c_str());
  }
}

// A .vwz file: its container, codec, volume, size and ratio, then what the codec says.
void printContainer(const std::string& path) {
  const auto file = codec::ContainerFile::open(path);
  const auto& info = file.info();
  const double rawBytes =
      double(info.voxelCount()) * double(codec::scalarBytes(info.type)) * double(info.steps);
  std::printf("file        %s\n", path.c_str());
  if (info.steps > 1)
    std::printf("container   .vwz version %u, %d steps, checksums ok\n", file.version(),
                info.steps);
  else
    std::printf("container   .vwz version %u, %zu sections, checksums ok\n", file.version(),
                file.sections().sections.size());
  const codec::Codec* c = codec::findCodec(info.codec);
  if (c)
    std::printf("codec       %s\n", std::string(c->name()).c_str());
  else  // a file of a later voxwall: what the container says is still worth showing
    std::printf("codec       id %u, not in this build (it has: %s)\n", unsigned(info.codec),
                codec::codecNames().c_str());
  printVolumeLines(info.dims, info.type, info.spacing, info.orientation, info.valueMin,
                   info.valueMax);
  std::printf("size        %s (%llu bytes)\n", humanBytes(double(file.fileBytes())).c_str(),
              (unsigned long long)file.fileBytes());
  std::printf("bits/voxel  %.3f (the voxels: %d)\n",
              8.0 * double(file.fileBytes()) / double(info.voxelCount()) / double(info.steps),
              int(8 * codec::scalarBytes(info.type)));
  std::printf("ratio       %.3f : 1 (uncompressed %s%s)\n", rawBytes / double(file.fileBytes()),
              humanBytes(rawBytes).c_str(),
              double(file.fileBytes()) > rawBytes ? "; the file is larger than its voxels" : "");
  if (c) printCodecLines(file, *c);
}

// A DICOM input: its images when the series holds several, then the picked image's time steps
// and step 0.
void printDicom(const InfoOptions& o) {
  const codec::DicomOptions options = o.raw.readOptions().dicom;
  const auto images = codec::listDicomImages(o.input, options);
  std::printf("file        %s\n", o.input.c_str());
  if (images.size() > 1) {
    std::printf("images      %zu (read one with --dicom-image N)\n", images.size());
    for (std::size_t i = 0; i < images.size(); ++i) {
      const codec::DicomImageInfo& image = images[i];
      std::printf("  %zu: %s, %d slices", i + 1, image.label.c_str(), image.slices);
      if (image.steps > 1)
        std::printf(", %d time steps ordered by %s", image.steps, image.orderedBy.c_str());
      std::printf("\n");
    }
    if (options.image == 0) return;
  }
  const codec::DicomInput input(o.input, options);
  if (input.steps() > 1)
    std::printf("steps       %s (step 0 below; `voxwall compress` makes one .vwz of them)\n",
                input.describeSteps().c_str());
  codec::Volume v = input.read(0);
  o.raw.applyOverrides(v);
  printVolumeLines(v.dims, v.type, v.spacing, v.orientation, v.valueMin, v.valueMax);
  std::printf("size        %s uncompressed\n", humanBytes(double(v.data.size())).c_str());
}

void runInfo(const InfoOptions& o) {
  if (o.raw.dims.empty() && codec::isContainerFile(o.input)) {
    printContainer(o.input);
    return;
  }
  std::error_code ec;
  if (o.raw.dims.empty() && std::filesystem::exists(o.input, ec) &&
      codec::volumeFormatOf(o.input) == codec::VolumeFormat::Dicom) {
    printDicom(o);
    return;
  }
  if (o.raw.dims.empty() && std::filesystem::is_regular_file(o.input) &&
      codec::volumeStepCount(o.input) > 1) {
    // A 4D NIfTI or NRRD series: its first step, and how many there are.
    codec::Volume v = codec::readVolumeStep(o.input, 0);
    o.raw.applyOverrides(v);
    std::printf("file        %s\n", o.input.c_str());
    std::printf("steps       %d (step 0 below; `voxwall compress` makes one .vwz of them)\n",
                codec::volumeStepCount(o.input));
    printVolumeLines(v.dims, v.type, v.spacing, v.orientation, v.valueMin, v.valueMax);
    return;
  }
  codec::Volume v = loadVolume(o.input, o.raw.readOptions());
  o.raw.applyOverrides(v);
  std::printf("file        %s\n", o.input.c_str());
  printVolumeLines(v.dims, v.type, v.spacing, v.orientation, v.valueMin, v.valueMax);
  std::printf("size        %s uncompressed\n", humanBytes(double(v.data.size())).c_str());
}

}  // namespace

void addInfoCommand(CLI::App& app) {
  auto o = std::make_shared<InfoOptions>();
  auto* cmd = app.add_subcommand(
      "info",
      "Describe a .vwz file (codec, dims, type, size, bits per voxel, ratio; verifies every "
      "checksum) or any readable volume");
  cmd->add_option("input", o->input, ".vwz file or any volume input")->required();
  o->raw.addTo(*cmd);
  cmd->callback([o] { runInfo(*o); });
}

}  // namespace voxwall::cli
