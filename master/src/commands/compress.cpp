#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/process.hpp>
#include <voxwall/core/text.hpp>
#include <voxwall/master/render_job.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct CompressOptions {
  // Without --codec: raw bricks, uncompressed (the format the raw codec stores as it is).
  std::string input, output, codec = codec::codecName(codec::rawbricks::kCodecId);
  int threads = 0;
  bool quiet = false, allowLarger = false, stepsAlone = false;
  RawInputOptions raw;
  codec::SeriesInput series;
  std::map<std::string, std::string> codecFlags;  // given: flag -> value
};

// The values of the options given for `chosen`; refuses an option of another codec.
codec::CodecOptionValues codecOptionValues(const CompressOptions& o, const codec::Codec& chosen) {
  codec::CodecOptionValues values;
  values.threads = o.threads;
  values.stepsAlone = o.stepsAlone;
  for (const auto& [flag, value] : o.codecFlags) {
    const auto own = chosen.options();
    if (std::none_of(own.begin(), own.end(), [&](const auto& spec) { return spec.flag == flag; }))
      throw std::invalid_argument(flag + " needs --codec " +
                                  codec::codecsTaking(flag, &codec::Codec::options));
    values.set(flag, value);
  }
  return values;
}

// A file larger than the voxels it codes is refused (unless --allow-larger): the data does not
// suit the codec, and zfp's lossless mode, which stores a brick as it is wherever coding would
// enlarge it, never outgrows them.
template <class Compressed>
void refuseLarger(const CompressOptions& o, const codec::Codec& chosen,
                  const Compressed& compressed) {
  if (o.allowLarger || !chosen.compresses() || !codec::largerThanVoxels(compressed)) return;
  const codec::VolumeInfo& info = compressed.info;
  throw std::invalid_argument(formatLine(
      "codec %s takes %.2f bits per voxel on this volume, more than its %d-bit voxels (the data "
      "does not suit it): use --codec zfp --lossless (never larger than the voxels) or a lossy "
      "setting, or --allow-larger to write it anyway",
      o.codec.c_str(),
      8.0 * double(compressed.payloadBytes()) / double(info.voxelCount()) / double(info.steps),
      int(8 * codec::scalarBytes(info.type))));
}

// A time series: every step encoded (by the codec's encodeSeries), one file.
void compressSeries(const CompressOptions& o, const codec::Codec& chosen,
                    const codec::CodecOptionValues& values, const codec::SeriesSource& series,
                    std::chrono::steady_clock::time_point start) {
  if (!o.raw.spacing.empty() || !o.raw.orientation.empty())
    throw std::invalid_argument(
        "--spacing and --orientation are not taken for a series yet: give each step's file its "
        "geometry");
  voxwall::Progress progress = makeProgress(o.quiet);
  std::string report;
  std::uint64_t fileBytes = 0;
  codec::CompressedSeries compressed;
  try {
    compressed = chosen.encodeSeries(series, values, progress, report);
    refuseLarger(o, chosen, compressed);
    fileBytes = codec::writeContainer(compressed, o.output);
  } catch (const std::bad_alloc&) {
    throw voxwall::FormatError(o.output,
                               "not enough memory to compress the series with codec " + o.codec);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::uint64_t peak = processMemory().peakBytes;
  const codec::VolumeInfo& info = compressed.info;
  std::uint64_t shared = 0;
  for (const auto& s : compressed.shared) shared += s.second.size();
  const double voxels = double(info.voxelCount()) * double(info.steps);
  std::printf(
      "%s: %d steps of %dx%dx%d %s, codec %s, %s, %.3f bits/voxel (%s shared by every step), "
      "values %g .. %g, %.2fs, peak memory %s%s\n",
      o.output.c_str(), info.steps, info.dims.x, info.dims.y, info.dims.z,
      std::string(codec::scalarName(info.type)).c_str(), o.codec.c_str(),
      humanBytes(double(fileBytes)).c_str(), 8.0 * double(fileBytes) / voxels,
      humanBytes(double(shared)).c_str(), info.valueMin, info.valueMax, seconds,
      humanBytes(double(peak)).c_str(), report.c_str());
}

void runCompress(const CompressOptions& o) {
  const codec::Codec& chosen = codec::codecNamed(o.codec);
  const codec::CodecOptionValues values = codecOptionValues(o, chosen);
  const auto start = std::chrono::steady_clock::now();
  if (o.input.empty() && o.series.files.empty())
    throw std::invalid_argument("give the input volume (or the steps of a series, --time-files)");
  if (const auto series = codec::openSeries(o.input, o.raw.readOptions(), o.series))
    return compressSeries(o, chosen, values, *series, start);
  voxwall::Progress progress = makeProgress(o.quiet);
  // Raw, NRRD (raw encoding) and uncompressed NIfTI files are read a slab at a time by the codecs
  // that stream; anything else is read whole first.
  const std::unique_ptr<codec::VolumeSource> source =
      o.input.rfind("generated:", 0) == 0
          ? codec::memorySource(loadVolume(o.input, o.raw.readOptions()))
          : codec::openVolumeSource(o.input, o.raw.readOptions(), progress);
  o.raw.applyOverrides(*source);
  std::string report;
  std::uint64_t fileBytes = 0;
  try {
    const codec::CompressedVolume compressed =
        chosen.encodeSource(*source, values, progress, report);
    refuseLarger(o, chosen, compressed);
    fileBytes = codec::writeContainer(compressed, o.output);
  } catch (const std::bad_alloc&) {
    throw voxwall::FormatError(o.input,
                               "not enough memory to compress it with codec " + o.codec +
                                   (source->streams() ? "" : " (the input was read whole)"));
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // The process's peak resident memory (the input, the encoder's work and the output together):
  // VmHWM, which starts over at exec (getrusage's maximum keeps a large parent's pages).
  const std::uint64_t peak = processMemory().peakBytes;
  const codec::Volume v = source->headerVolume();
  std::printf("%s: %dx%dx%d %s, codec %s, %s, %.3f bits/voxel, %.2fs, peak memory %s%s\n",
              o.output.c_str(), v.dims.x, v.dims.y, v.dims.z,
              std::string(codec::scalarName(v.type)).c_str(), o.codec.c_str(),
              humanBytes(double(fileBytes)).c_str(), codec::bitsPerVoxel(fileBytes, v), seconds,
              humanBytes(double(peak)).c_str(), report.c_str());
}

}  // namespace

void addCompressCommand(CLI::App& app) {
  auto o = std::make_shared<CompressOptions>();
  auto* cmd = app.add_subcommand("compress", "Compress a volume file into a .vwz container");
  cmd->add_option("input", o->input,
                  "Volume: .nii/.nii.gz, .nrrd/.nhdr, .raw (with --dims/--type), .tif/.tiff, a "
                  "directory of slices, DICOM, or generated:KIND:SIZE. A time series: a 4D "
                  "NIfTI, a file pattern ('sim_%04d.nrrd': every file it prints, in number "
                  "order), a raw file of several volumes (--time N), or --time-files");
  cmd->add_option("-o,--output", o->output, "Output .vwz file")->required();
  std::string codecHelp = "Codec:";
  for (const codec::Codec* c : codec::codecs())
    codecHelp += " '" + std::string(c->name()) + "': " + std::string(c->summary()) + ";";
  codecHelp.back() = '.';
  cmd->add_option("--codec", o->codec, codecHelp + " `voxwall codecs` lists them with examples")
      ->capture_default_str();
  addCodecFlags(*cmd, &codec::Codec::options, o->codecFlags);
  cmd->add_option("--threads", o->threads, "Encoder threads (0: every usable core)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("-q,--quiet", o->quiet, "No progress output");
  cmd->add_flag("--allow-larger", o->allowLarger,
                "Write the file even where the codec makes it larger than the voxels (refused "
                "by default: the data does not suit that codec)");
  o->raw.addTo(*cmd);
  cmd->add_option("--time-files", o->series.files,
                  "The steps of a time series, one 3D volume file each, in order (instead of the "
                  "input)");
  cmd->add_option("--time", o->series.rawSteps,
                  "A raw input holds this many volumes of --dims one after the other: a series")
      ->check(CLI::Range(1, int(codec::kMaxSteps)));
  cmd->add_flag("--steps-alone", o->stepsAlone,
                "A series: code every step on its own (by default a codec that can shares one "
                "model across the steps: ksvd one dictionary)");
  cmd->callback([o] { runCompress(*o); });
}

}  // namespace voxwall::cli
