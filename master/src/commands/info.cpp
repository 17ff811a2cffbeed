#include <cmath>
#include <cstdio>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/vq_codec.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct InfoOptions {
  std::string input;
  RawInputOptions raw;
};

void printVolumeLines(glm::ivec3 dims, codec::ScalarType type, glm::dvec3 spacing, double lo,
                      double hi) {
  std::printf("dims        %d x %d x %d (%zu voxels)\n", dims.x, dims.y, dims.z,
              std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z));
  std::printf("type        %s\n", std::string(codec::scalarName(type)).c_str());
  std::printf("spacing     %g x %g x %g\n", spacing.x, spacing.y, spacing.z);
  std::printf("values      %g .. %g\n", lo, hi);
}

void runInfo(const InfoOptions& o) {
  if (o.raw.dims.empty() && codec::isContainerFile(o.input)) {
    const auto file = codec::ContainerFile::open(o.input);
    const auto& info = file.info();
    const double rawBytes = double(info.voxelCount()) * double(codec::scalarBytes(info.type));
    std::printf("file        %s\n", o.input.c_str());
    std::printf("container   .vwz version %u, %zu sections, checksums ok\n",
                codec::kContainerVersion, file.sections().sections.size());
    std::printf("codec       %s\n", std::string(codec::codecName(info.codec)).c_str());
    printVolumeLines(info.dims, info.type, info.spacing, info.valueMin, info.valueMax);
    std::printf("size        %s (%llu bytes)\n", humanBytes(double(file.fileBytes())).c_str(),
                (unsigned long long)file.fileBytes());
    std::printf("bits/voxel  %.3f\n", 8.0 * double(file.fileBytes()) / double(info.voxelCount()));
    std::printf("ratio       %.3f : 1 (uncompressed %s)\n", rawBytes / double(file.fileBytes()),
                humanBytes(rawBytes).c_str());
    if (info.codec == codec::CodecId::Raw) {
      const codec::raw::Layout layout(info, file.sections());
      const int b = 1 << layout.brickShift();
      const glm::ivec3 b3 = layout.bricks(), cells = layout.rangeCells();
      std::printf("bricks      %d x %d x %d of %d^3 voxels (stored as %d^3 with their apron)\n",
                  b3.x, b3.y, b3.z, b, b + 1);
      std::printf("ranges      %d x %d x %d cells of %d^3 voxels\n", cells.x, cells.y, cells.z,
                  layout.rangeCellVoxels());
    }
    if (info.codec == codec::CodecId::Vq) {
      const codec::vq::Layout layout(info, file.sections());
      const glm::ivec3 b3 = (info.dims + 3) / 4;
      const bool compressed = layout.flags() & codec::vq::kCompressed;
      std::printf("bricks      %d x %d x %d of 4^3 voxels, %llu codewords of %d-bit values\n", b3.x,
                  b3.y, b3.z, (unsigned long long)layout.codewords(), layout.bits());
      std::printf("codebook    %s, %s (%s)\n", compressed ? "RBUC-compressed" : "plain bit-packed",
                  humanBytes(double(layout.codebookBytes())).c_str(),
                  !compressed                               ? "offset volume holds indices"
                  : (layout.flags() & codec::vq::kIndirect) ? "indirect mapping: index table"
                                                            : "direct mapping: byte addresses");
      if (layout.reduction() > 1 || !std::isinf(layout.psnr()))
        std::printf("quality     lossy, 1/%d of the unique bricks, PSNR %.2f dB\n",
                    layout.reduction(), layout.psnr());
      else
        std::printf("quality     lossless\n");
    }
    if (info.codec == codec::CodecId::Svmm) {
      const codec::svmm::Layout layout(info, file.sections());
      static const char* kFormats[] = {"", "DENSITY8", "DENSITY16", "RGBA32"};
      std::string widths, blocks;
      for (int i = 0; i < layout.levels(); ++i) {
        const std::string sep = i ? ", " : "";
        widths += sep + (i + 1 < layout.levels() ? std::to_string(layout.widths()[std::size_t(i)])
                                                 : std::string("root"));
        blocks += sep + std::to_string(layout.blocks()[std::size_t(i)]);
      }
      std::printf("voxels      %s%s\n", kFormats[layout.format()],
                  (layout.flags() & codec::svmm::kBlockCompressed) && layout.levels() > 1
                      ? ", base blocks compressed (bitmap + one value per 2^3)"
                      : "");
      std::printf("levels      %d (block widths %s%s; root width %d)\n", layout.levels(),
                  widths.c_str(), layout.stepped() ? ", stepped" : "", layout.rootWidth());
      std::printf("blocks      %s (per level, from the base)\n", blocks.c_str());
      if (std::isinf(layout.psnr()))
        std::printf("quality     %d, lossless\n", layout.quality());
      else
        std::printf("quality     %d (delta %.4g), PSNR %.2f dB\n", layout.quality(), layout.delta(),
                    layout.psnr());
    }
    return;
  }
  codec::Volume v = loadVolume(o.input, o.raw.layout());
  if (!o.raw.spacing.empty()) v.spacing = parseSpacing(o.raw.spacing, "--spacing");
  std::printf("file        %s\n", o.input.c_str());
  printVolumeLines(v.dims, v.type, v.spacing, v.valueMin, v.valueMax);
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
