#include "cli_common.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/core/errors.hpp>

namespace voxwall::cli {

void RawInputOptions::addTo(CLI::App& app) {
  app.add_option("--dims", dims, "Raw input only: voxels per axis, X,Y,Z (x fastest in the file)");
  app.add_option("--type", type, "Raw input only: scalar type: uint8, uint16, int16 or float32")
      ->capture_default_str();
  app.add_option("--spacing", spacing,
                 "Voxel spacing X,Y,Z in world units (mm); overrides the file's for any input");
  app.add_option("--orientation", orientation,
                 "Where the x, y and z axes point in the patient, as three letters of R/L, A/P, "
                 "S/I (e.g. RAS: x to the right, y anterior, z superior); overrides the file's "
                 "orientation for any input (raw files and slice stacks have none: LPS)");
  app.add_flag("--big-endian", bigEndian, "Raw input only: multi-byte values are big-endian");
  app.add_option("--header-bytes", headerBytes, "Raw input only: bytes to skip before the voxels");
  app.add_option("--series", series,
                 "DICOM input only: the Series Instance UID to read when the folder holds several "
                 "(without it such a folder is refused with a list of its series)");
  app.add_option("--dicom-image", dicomImage,
                 "DICOM input only: which image of a series or enhanced file that holds "
                 "several at each position (echoes, image types, b-values, stacks), from 1 in "
                 "the order of their first slices; without it such a series is refused with a "
                 "list of its images (`info` lists them). Repeats that differ only in time are "
                 "time steps, not images")
      ->check(CLI::PositiveNumber);
  app.add_flag("--resample-tilt", resampleTilt,
               "DICOM input only: resample a series acquired with a gantry tilt (its slices "
               "sheared) onto a box, instead of refusing it");
}

codec::ReadOptions RawInputOptions::readOptions() const {
  codec::ReadOptions options(layout());
  options.dicom.series = series;
  options.dicom.resampleTilt = resampleTilt;
  options.dicom.image = dicomImage;
  return options;
}

void RawInputOptions::applyOverrides(codec::Volume& volume) const {
  if (!spacing.empty()) volume.spacing = parseSpacing(spacing, "--spacing");
  if (!orientation.empty())
    volume.orientation.direction = codec::parseOrientationLetters(orientation);
}

void RawInputOptions::applyOverrides(codec::VolumeSource& source) const {
  if (!spacing.empty()) source.setSpacing(parseSpacing(spacing, "--spacing"));
  if (!orientation.empty()) {
    codec::Orientation o = source.orientation;
    o.direction = codec::parseOrientationLetters(orientation);
    source.setOrientation(o);
  }
}

std::optional<codec::RawLayout> RawInputOptions::layout() const {
  if (dims.empty()) return std::nullopt;
  codec::RawLayout l;
  l.dims = parseDims(dims, "--dims");
  l.type = codec::parseScalarType(type);
  if (!spacing.empty()) l.spacing = parseSpacing(spacing, "--spacing");
  if (!orientation.empty()) l.orientation.direction = codec::parseOrientationLetters(orientation);
  l.bigEndian = bigEndian;
  l.headerBytes = headerBytes;
  return l;
}

std::vector<double> parseNumbers(const std::string& text, const std::string& option) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      const double v = std::stod(item, &used);
      if (used != item.size() || !std::isfinite(v)) throw std::invalid_argument(item);
      out.push_back(v);
    } catch (const std::exception&) {
      throw std::invalid_argument(option + ": '" + text +
                                  "' is not a comma-separated list of numbers");
    }
  }
  return out;
}

glm::ivec3 parseDims(const std::string& text, const std::string& option) {
  const auto v = parseNumbers(text, option);
  if (v.size() != 3) throw std::invalid_argument(option + ": expected X,Y,Z, got '" + text + "'");
  glm::ivec3 d;
  for (int i = 0; i < 3; ++i) {
    if (v[i] < 1 || v[i] != std::floor(v[i]) || v[i] > (1 << 24))
      throw std::invalid_argument(option + ": '" + text + "' must be three positive integers");
    d[i] = int(v[i]);
  }
  return d;
}

glm::dvec3 parseSpacing(const std::string& text, const std::string& option) {
  const auto v = parseNumbers(text, option);
  if (v.size() != 3 || !(v[0] > 0 && v[1] > 0 && v[2] > 0))
    throw std::invalid_argument(option + ": expected three positive numbers X,Y,Z, got '" + text +
                                "'");
  return {v[0], v[1], v[2]};
}

std::pair<int, int> parseSize(const std::string& text, const std::string& option) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') ||
      w < 1 || h < 1 || w > 65536 || h > 65536)
    throw std::invalid_argument(option + ": expected WIDTHxHEIGHT (e.g. 1920x1080), got '" + text +
                                "'");
  return {w, h};
}

codec::Volume loadVolume(const std::string& spec, const codec::ReadOptions& options) {
  if (spec.rfind("generated:", 0) == 0) {
    std::stringstream ss(spec.substr(10));
    std::string kind, param;
    std::getline(ss, kind, ':');
    std::getline(ss, param);
    int n = 0;
    try {
      n = param.empty() ? 0 : std::stoi(param);
    } catch (const std::exception&) {
      throw std::invalid_argument("'" + spec + "': size must be an integer");
    }
    if (kind == "menger") return codec::generateMenger(n ? n : 4);
    if (kind == "marschner-lobb") return codec::generateMarschnerLobb(n ? n : 64);
    if (kind == "shepp-logan") return codec::generateSheppLogan(n ? n : 256);
    throw std::invalid_argument("'" + spec +
                                "': expected generated:menger:LEVEL, generated:marschner-lobb:N or "
                                "generated:shepp-logan:N");
  }
  return codec::readVolume(spec, options);
}

void addCodecFlags(CLI::App& cmd, std::vector<codec::CodecOption> (codec::Codec::*list)() const,
                   std::map<std::string, std::string>& given) {
  std::map<std::string, CLI::Option*> registered;
  for (const codec::Codec* c : codec::codecs())
    for (const codec::CodecOption& spec : (c->*list)()) {
      if (CLI::Option* known = registered[spec.flag]) {
        known->description(known->get_description() + "; " + spec.help);
        continue;
      }
      const std::string flag = spec.flag;
      CLI::Option* opt =
          spec.isFlag
              ? cmd.add_flag_callback(
                    flag, [&given, flag] { given[flag] = "1"; }, spec.help)
              : cmd.add_option(flag, spec.help)->each([&given, flag](const std::string& value) {
                  given[flag] = value;
                });
      if (!spec.defaultValue.empty()) opt->default_str(spec.defaultValue);
      registered[flag] = opt;
    }
}

voxwall::Progress makeProgress(bool quiet) {
  if (quiet) return voxwall::Progress{};
  const bool tty = ::isatty(2);
  return voxwall::Progress(
      [tty](const std::string& stage, std::uint64_t done, std::uint64_t total) {
        const int percent = total ? int(100 * done / total) : 100;
        if (tty) {
          const int width = 30, filled = percent * width / 100;
          std::fprintf(stderr, "\r%-12s [%s%s] %3d%%", stage.c_str(),
                       std::string(std::size_t(filled), '#').c_str(),
                       std::string(std::size_t(width - filled), '.').c_str(), percent);
          if (done >= total) std::fputc('\n', stderr);
        } else if (done >= total) {
          std::fprintf(stderr, "%s: done\n", stage.c_str());
        }
        std::fflush(stderr);
      });
}

bool isNonZeroRank() {
  for (const char* name : {"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"})
    if (const char* value = std::getenv(name)) return std::string(value) != "0";
  return false;
}

}  // namespace voxwall::cli
