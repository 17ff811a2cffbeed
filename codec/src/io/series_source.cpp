// Time series inputs: a 4D NIfTI file, a file pattern, a list of files, a raw file of several
// volumes.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/core/errors.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {
namespace {

// "64x64x32 uint8, spacing 1 x 1 x 2"
std::string describe(glm::ivec3 dims, ScalarType type, glm::dvec3 spacing) {
  char text[160];
  std::snprintf(text, sizeof text, "%dx%dx%d %s, spacing %g x %g x %g", dims.x, dims.y, dims.z,
                std::string(scalarName(type)).c_str(), spacing.x, spacing.y, spacing.z);
  return text;
}

// The printf conversion of a pattern: where it starts and its length.
struct Conversion {
  std::size_t at = std::string::npos, length = 0;
};

Conversion conversionOf(const std::string& name) {
  static const std::regex conversion("%0?[0-9]*d");
  std::smatch m;
  if (!std::regex_search(name, m, conversion)) return {};
  return {std::size_t(m.position(0)), std::size_t(m.length(0))};
}

std::string printed(const std::string& pattern, long long n) {
  char text[4096];
  std::snprintf(text, sizeof text, pattern.c_str(), n);
  return text;
}

// Every file in the pattern's folder that the pattern prints for some number, in number order.
std::vector<SeriesSource::Step> patternSteps(const std::string& path) {
  const std::filesystem::path p(path);
  const std::filesystem::path folder = p.has_parent_path() ? p.parent_path() : ".";
  const std::string name = p.filename().string();
  const Conversion c = conversionOf(name);
  if (c.at == std::string::npos || name.find('%', c.at + c.length) != std::string::npos ||
      name.find('%') != c.at)
    throw std::invalid_argument(path +
                                ": a file pattern holds one integer conversion (%d, %04d) and no "
                                "other %");
  // printf with the conversion as %lld, the rest of the name as it is.
  const std::string format =
      name.substr(0, c.at) + name.substr(c.at, c.length - 1) + "lld" + name.substr(c.at + c.length);
  const std::string head = name.substr(0, c.at), tail = name.substr(c.at + c.length);
  std::vector<std::pair<long long, std::string>> found;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(folder, ec)) {
    const std::string file = entry.path().filename().string();
    if (file.size() <= head.size() + tail.size() || !file.starts_with(head) ||
        !file.ends_with(tail))
      continue;
    const std::string digits = file.substr(head.size(), file.size() - head.size() - tail.size());
    if (digits.size() > 15 ||
        !std::all_of(digits.begin(), digits.end(), [](char d) { return d >= '0' && d <= '9'; }))
      continue;
    const long long n = std::stoll(digits);
    if (printed(format, n) == file) found.emplace_back(n, (folder / file).string());
  }
  if (ec) throw FormatError(folder.string(), ec.message());
  if (found.empty()) throw FormatError(path, "no file in " + folder.string() + " matches");
  std::sort(found.begin(), found.end());
  std::vector<SeriesSource::Step> steps;
  for (const auto& [n, file] : found)
    steps.push_back({std::filesystem::path(file).filename().string(), file});
  return steps;
}

// The `count` volumes of one file, "<name> step k".
std::vector<SeriesSource::Step> volumesOf(const std::string& path, int count,
                                          SeriesSource::Kind kind) {
  std::vector<SeriesSource::Step> steps;
  std::filesystem::path named(path);
  if (!named.has_filename()) named = named.parent_path();  // a folder given as "dicom/"
  const std::string name = named.filename().string();
  for (int k = 0; k < count; ++k)
    steps.push_back({name + " step " + std::to_string(k), path, k, kind});
  return steps;
}

}  // namespace

SeriesSource::SeriesSource(std::vector<Step> steps, ReadOptions options,
                           std::shared_ptr<const DicomInput> dicom)
    : steps_(std::move(steps)), options_(std::move(options)), dicom_(std::move(dicom)) {
  if (steps_.empty()) throw std::invalid_argument("a series of no steps");
  if (steps_.size() > kMaxSteps)
    throw std::invalid_argument(std::to_string(steps_.size()) +
                                " steps: a .vwz file holds at most " + std::to_string(kMaxSteps));
}

std::unique_ptr<VolumeSource> SeriesSource::read(int k, Progress& progress) const {
  const Step& step = steps_.at(std::size_t(k));
  switch (step.kind) {
    case Kind::RawVolume: {
      SlabLayout slab{step.file, *options_.raw};
      slab.layout.headerBytes += std::uint64_t(step.index) * std::uint64_t(slab.layout.dims.x) *
                                 std::uint64_t(slab.layout.dims.y) *
                                 std::uint64_t(slab.layout.dims.z) * scalarBytes(slab.layout.type);
      return slabSource(step.file, slab, progress);
    }
    case Kind::FileVolume: {
      const bool nrrd = volumeFormatOf(step.file) == VolumeFormat::Nrrd;
      if (auto slab =
              nrrd ? nrrdSlabLayout(step.file, step.index) : niftiSlabLayout(step.file, step.index))
        return slabSource(step.file, *slab, progress);
      return memorySource(readVolumeStep(step.file, step.index));
    }
    case Kind::DicomStep:
      return memorySource(dicom_->read(step.index));
    case Kind::File:
      break;
  }
  return openVolumeSource(step.file, options_, progress);
}

std::unique_ptr<VolumeSource> SeriesSource::open(int k, Progress& progress) const {
  if (!haveFirst_ && k != 0) (void)open(0, progress);
  std::unique_ptr<VolumeSource> source = read(k, progress);
  if (!haveFirst_) {
    dims_ = source->dims, type_ = source->type, spacing_ = source->spacing;
    haveFirst_ = true;
    return source;
  }
  if (source->dims != dims_ || source->type != type_ || source->spacing != spacing_)
    throw FormatError(steps_[std::size_t(k)].file,
                      "step " + std::to_string(k) + " (" + stepName(k) + ") is " +
                          describe(source->dims, source->type, source->spacing) + ", but step 0 (" +
                          stepName(0) + ") is " + describe(dims_, type_, spacing_) +
                          ": every step must agree in size, type and spacing");
  return source;
}

bool isStepPattern(const std::string& path) {
  return conversionOf(std::filesystem::path(path).filename().string()).at != std::string::npos &&
         !std::filesystem::exists(path);
}

std::unique_ptr<SeriesSource> openSeries(const std::string& path, const ReadOptions& options,
                                         const SeriesInput& input) {
  std::vector<SeriesSource::Step> steps;
  if (!input.files.empty()) {
    if (!path.empty())
      throw std::invalid_argument("give the input volume or --time-files, not both");
    if (input.rawSteps > 0)
      throw std::invalid_argument("--time N reads one raw file; --time-files names each step");
    for (const std::string& file : input.files) {
      const int count = volumeStepCount(file);
      if (count > 1)
        throw FormatError(file, "holds " + std::to_string(count) +
                                    " steps itself; --time-files takes one volume a file");
      steps.push_back({std::filesystem::path(file).filename().string(), file});
    }
    return std::make_unique<SeriesSource>(std::move(steps), options);
  }
  if (input.rawSteps > 0) {
    if (!options.isRaw())
      throw std::invalid_argument("--time N reads a raw file of N volumes: give --dims too");
    if (input.rawSteps > int(kMaxSteps))
      throw std::invalid_argument("--time " + std::to_string(input.rawSteps) +
                                  ": a .vwz file holds at most " + std::to_string(kMaxSteps) +
                                  " steps");
    // The file holds the volumes one after the other: its size is checked as one volume of N
    // times the slices.
    RawLayout all = *options.raw;
    all.dims.z *= input.rawSteps;
    checkRawFile(path, all);
    return std::make_unique<SeriesSource>(
        volumesOf(path, input.rawSteps, SeriesSource::Kind::RawVolume), options);
  }
  if (isStepPattern(path)) return std::make_unique<SeriesSource>(patternSteps(path), options);
  std::error_code ec;
  if (!options.isRaw() && std::filesystem::exists(path, ec) &&
      volumeFormatOf(path) == VolumeFormat::Dicom) {
    auto dicom = std::make_shared<const DicomInput>(path, options.dicom);
    if (dicom->steps() <= 1) return nullptr;
    return std::make_unique<SeriesSource>(
        volumesOf(path, dicom->steps(), SeriesSource::Kind::DicomStep), options, std::move(dicom));
  }
  if (!options.isRaw() && std::filesystem::is_regular_file(path, ec)) {
    const int count = volumeStepCount(path);
    if (count <= 1) return nullptr;
    return std::make_unique<SeriesSource>(volumesOf(path, count, SeriesSource::Kind::FileVolume),
                                          options);
  }
  return nullptr;
}

}  // namespace voxwall::codec
