#include <chrono>
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

struct CompressOptions {
  std::string input, output, codec = "raw";
  int brick = codec::raw::Params{}.brickVoxels;
  int rangeCell = codec::raw::Params{}.rangeCellVoxels;
  int reduction = 1;
  double bitsPerVoxel = 0;
  std::string codebook = "compressed";
  int quality = 100;
  std::string blockWidth = "4";
  int rootWidth = 32;
  bool baseCompression = false;
  bool svmmOptionGiven = false;
  int threads = 0;
  bool quiet = false;
  RawInputOptions raw;
};

void runCompress(const CompressOptions& o) {
  const auto codecId = codec::parseCodecName(o.codec);
  if (codecId != codec::CodecId::Raw && codecId != codec::CodecId::Vq &&
      codecId != codec::CodecId::Svmm)
    throw std::invalid_argument("codec '" + o.codec +
                                "' is not implemented yet (available: raw, vq, svmm)");
  if (codecId != codec::CodecId::Svmm && o.svmmOptionGiven)
    throw std::invalid_argument(
        "--quality, --block-width, --root-width and --base-compression need --codec svmm");
  codec::svmm::Params sp;
  if (codecId == codec::CodecId::Svmm) {
    sp.quality = o.quality;
    sp.rootWidth = o.rootWidth;
    sp.baseCompression = o.baseCompression;
    sp.threads = o.threads;
    if (o.blockWidth == "stepped") {
      sp.stepped = true;
    } else {
      std::size_t used = 0;
      int w = 0;
      try {
        w = std::stoi(o.blockWidth, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != o.blockWidth.size() || w < 2 || w > 64 || (w & (w - 1)))
        throw std::invalid_argument(
            "--block-width must be a power of two in 2..64 or 'stepped', not '" + o.blockWidth +
            "'");
      sp.blockWidth = w;
    }
  }
  if (o.codebook != "compressed" && o.codebook != "plain")
    throw std::invalid_argument("--codebook must be 'compressed' or 'plain', not '" + o.codebook +
                                "'");
  if (codecId != codec::CodecId::Vq &&
      (o.reduction != 1 || o.bitsPerVoxel > 0 || o.codebook != "compressed"))
    throw std::invalid_argument("--reduction, --bits-per-voxel and --codebook need --codec vq");
  if (o.reduction != 1 && o.bitsPerVoxel > 0)
    throw std::invalid_argument("give --reduction or --bits-per-voxel, not both");
  const auto start = std::chrono::steady_clock::now();
  codec::Volume v = loadVolume(o.input, o.raw.layout());
  if (!o.raw.spacing.empty()) v.spacing = parseSpacing(o.raw.spacing, "--spacing");
  codec::Progress progress = makeProgress(o.quiet);
  codec::CompressedVolume compressed;
  std::string detail;
  if (codecId == codec::CodecId::Raw) {
    compressed = codec::raw::encode(v, {o.brick, o.rangeCell}, progress);
  } else if (codecId == codec::CodecId::Svmm) {
    codec::svmm::EncodeStats s;
    compressed = codec::svmm::encode(v, sp, progress, &s);
    std::string widths, blocks;
    for (int i = 0; i < s.levels; ++i) {
      const std::string sep = i ? ", " : "";
      widths += sep + (i + 1 < s.levels ? std::to_string(s.widths[std::size_t(i)]) : "root");
      blocks += sep + std::to_string(s.blocks[std::size_t(i)]);
    }
    char line[512];
    std::snprintf(line, sizeof line,
                  "\n  %d levels (block widths %s; blocks per level from the base: %s)%s"
                  "\n  quality %d (delta %.4g of the value range): ",
                  s.levels, widths.c_str(), blocks.c_str(),
                  sp.baseCompression && s.levels > 1 ? ", base blocks compressed" : "", sp.quality,
                  s.delta);
    detail = line;
    if (std::isinf(s.psnr)) {
      detail += "lossless";
    } else {
      std::snprintf(line, sizeof line, "PSNR %.2f dB", s.psnr);
      detail += line;
    }
  } else {
    codec::vq::Params p;
    p.reduction = o.reduction;
    p.targetBitsPerVoxel = o.bitsPerVoxel;
    p.compressedCodebook = o.codebook == "compressed";
    p.threads = o.threads;
    codec::vq::EncodeStats s;
    compressed = codec::vq::encode(v, p, progress, &s);
    char line[512];
    std::snprintf(line, sizeof line, "\n  %llu bricks, %llu unique, %llu codewords (%s, %s)",
                  (unsigned long long)s.bricks, (unsigned long long)s.uniqueBricks,
                  (unsigned long long)s.codewords, p.compressedCodebook ? "RBUC" : "plain",
                  !p.compressedCodebook ? "indices"
                  : s.indirect          ? "indirect mapping"
                                        : "direct mapping");
    detail = line;
    std::snprintf(line, sizeof line, "\n  offset volume %s, index table %s, codebook %s",
                  humanBytes(double(s.offsetVolumeBytes)).c_str(),
                  humanBytes(double(s.indexTableBytes)).c_str(),
                  humanBytes(double(s.codebookBytes)).c_str());
    detail += line;
    if (p.compressedCodebook) {
      std::snprintf(line, sizeof line,
                    "; codewords by predictor: none %llu, x %llu, xy %llu, xyz %llu, raw %llu",
                    (unsigned long long)s.transformUse[0], (unsigned long long)s.transformUse[1],
                    (unsigned long long)s.transformUse[2], (unsigned long long)s.transformUse[3],
                    (unsigned long long)s.escapes);
      detail += line;
    }
    if (s.codewords != s.uniqueBricks || s.reduction > 1) {
      const double plain = double(s.plainEquivalent);
      std::snprintf(line, sizeof line,
                    "\n  lossy: 1/%d of the unique bricks, PSNR %.2f dB; k-means %d iterations "
                    "in %.2fs: %.3g distances computed, %.3g skipped by the norm bound, %.0fx "
                    "fewer than plain Lloyd",
                    s.reduction, s.psnr, s.iterations, s.kmeansSeconds, double(s.distancesComputed),
                    double(s.distancesSkipped),
                    s.distancesComputed ? plain / double(s.distancesComputed) : 0.0);
      detail += line;
    } else {
      detail += "\n  lossless";
    }
  }
  const std::uint64_t fileBytes = codec::writeContainer(compressed, o.output);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s: %dx%dx%d %s, codec %s, %s, %.3f bits/voxel, %.2fs%s\n", o.output.c_str(),
              v.dims.x, v.dims.y, v.dims.z, std::string(codec::scalarName(v.type)).c_str(),
              o.codec.c_str(), humanBytes(double(fileBytes)).c_str(),
              codec::bitsPerVoxel(fileBytes, v), seconds, detail.c_str());
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
  cmd->add_option("--codec", o->codec,
                  "Codec: 'raw' (bricked, uncompressed), 'vq' (4^3 bricks deduplicated into a "
                  "codebook, lossless unless --reduction/--bits-per-voxel; 8/12/16-bit integer "
                  "data) or 'svmm' (sparse voxel mip-map: blocks within --quality of their mean "
                  "dropped; lossless at quality 100; 8/16-bit integer data)")
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
  cmd->add_option("--reduction", o->reduction,
                  "vq codec: keep 1/K of the unique bricks (k-means; K = 2, 4, ... 1024); 1 is "
                  "lossless")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  cmd->add_option("--bits-per-voxel", o->bitsPerVoxel,
                  "vq codec: choose the reduction for this size instead (bits per voxel of the "
                  "coded data; lossless when that already fits)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--codebook", o->codebook,
                  "vq codec: 'compressed' (RBUC variable-length codewords) or 'plain' (bit-packed "
                  "at the data's bit depth: faster to decode, larger)")
      ->capture_default_str();
  std::vector<CLI::Option*> svmmOptions;
  svmmOptions.push_back(
      cmd->add_option("--quality", o->quality,
                      "svmm codec: 0..100; a block is dropped when every voxel is within "
                      "sqrt(channels) x (1 - Q/100) x the value range of the block's mean; 100 is "
                      "lossless")
          ->check(CLI::Range(0, 100))
          ->capture_default_str());
  svmmOptions.push_back(cmd->add_option("--block-width", o->blockWidth,
                                        "svmm codec: block width of every level (2, 4, ... 64) "
                                        "or 'stepped' (2, 4, 8, ... from the base level up)")
                            ->capture_default_str());
  svmmOptions.push_back(
      cmd->add_option("--root-width", o->rootWidth,
                      "svmm codec: stop building levels once a level is at most this wide")
          ->check(CLI::Range(2, 1 << 20))
          ->capture_default_str());
  svmmOptions.push_back(cmd->add_flag(
      "--base-compression", o->baseCompression,
      "svmm codec: store base blocks as 2^3 groups of an occupancy bitmap and one shared value "
      "(lossy; the thesis's Fig. 1.2c)"));
  cmd->add_option("--threads", o->threads, "Encoder threads (0: every usable core)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("-q,--quiet", o->quiet, "No progress output");
  o->raw.addTo(*cmd);
  cmd->callback([o, svmmOptions] {
    for (const auto* opt : svmmOptions) o->svmmOptionGiven |= opt->count() > 0;
    runCompress(*o);
  });
}

}  // namespace voxwall::cli
