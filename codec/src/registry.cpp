#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <voxwall/codec/registry.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/core/errors.hpp>

namespace voxwall::codec {

std::unique_ptr<RenderPayload> Codec::openWith(const VolumeInfo& info, const SectionSet& sections,
                                               const CodecOptionValues& renderOptions) const {
  (void)renderOptions;  // a codec without render options ignores them
  return open(info, sections);
}

std::uint64_t mintCacheIds(std::uint64_t count) {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(count);
}

CompressedVolume Codec::encodeSource(const VolumeSource& source, const CodecOptionValues& options,
                                     Progress& progress, std::string& report) const {
  if (const Volume* whole = source.inMemory()) return encode(*whole, options, progress, report);
  const Volume volume = source.readAll();
  return encode(volume, options, progress, report);
}

CompressedSeries Codec::encodeSeries(const SeriesSource& series, const CodecOptionValues& options,
                                     Progress& progress, std::string& report) const {
  std::vector<CompressedVolume> steps;
  for (int k = 0; k < series.steps(); ++k) {
    progress.setPrefix("step " + std::to_string(k + 1) + "/" + std::to_string(series.steps()) +
                       ": ");
    const std::unique_ptr<VolumeSource> source = series.open(k, progress);
    std::string stepReport;
    steps.push_back(encodeSource(*source, options, progress, stepReport));
    if (k == 0) report += stepReport;
  }
  progress.setPrefix("");
  return makeSeries(std::move(steps));
}

std::string CodecOptionValues::text(const std::string& flag, const std::string& fallback) const {
  const auto it = values_.find(flag);
  return it == values_.end() ? fallback : it->second;
}

int CodecOptionValues::integer(const std::string& flag, int fallback, int lo, int hi) const {
  const auto it = values_.find(flag);
  if (it == values_.end()) return fallback;
  std::size_t used = 0;
  long long value = 0;
  try {
    value = std::stoll(it->second, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != it->second.size() || value < lo || value > hi)
    throw std::invalid_argument(flag + " must be an integer in " + std::to_string(lo) + ".." +
                                std::to_string(hi) + ", not '" + it->second + "'");
  return int(value);
}

double CodecOptionValues::number(const std::string& flag, double fallback, double lo,
                                 double hi) const {
  const auto it = values_.find(flag);
  if (it == values_.end()) return fallback;
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(it->second, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != it->second.size() || !std::isfinite(value) || value < lo || value > hi) {
    char range[96];
    std::snprintf(range, sizeof range, "a number in [%g, %g]", lo, hi);
    throw std::invalid_argument(flag + " must be " + range + ", not '" + it->second + "'");
  }
  return value;
}

const std::vector<const Codec*>& codecs() { return RegisteredCodecs::objects(); }

bool largerThanVoxels(const CompressedVolume& compressed) {
  const std::uint64_t voxels = compressed.info.voxelCount() * scalarBytes(compressed.info.type);
  return compressed.payloadBytes() > voxels + voxels / 256 + 4096;
}

bool largerThanVoxels(const CompressedSeries& compressed) {
  const std::uint64_t voxels =
      compressed.info.voxelCount() * scalarBytes(compressed.info.type) * compressed.steps.size();
  return compressed.payloadBytes() > voxels + voxels / 256 + 4096 * compressed.steps.size();
}

const Codec* findCodec(CodecId id) {
  for (const Codec* c : codecs())
    if (c->id() == id) return c;
  return nullptr;
}

std::string codecNames() {
  std::string names;
  for (const Codec* c : codecs()) names += (names.empty() ? "" : ", ") + std::string(c->name());
  return names;
}

std::string codecsTaking(const std::string& flag, std::vector<CodecOption> (Codec::*list)() const) {
  std::string owners;
  for (const Codec* c : codecs())
    for (const CodecOption& o : (c->*list)())
      if (o.flag == flag) owners += (owners.empty() ? "" : " or ") + std::string(c->name());
  return owners;
}

const Codec& codecNamed(std::string_view name) {
  for (const Codec* c : codecs())
    if (c->name() == name) return *c;
  throw std::invalid_argument("unknown codec '" + std::string(name) +
                              "' (this build has: " + codecNames() + ")");
}

std::string codecName(CodecId id) {
  if (const Codec* c = findCodec(id)) return std::string(c->name());
  return "id " + std::to_string(std::uint32_t(id));
}

const Codec& codecOf(const VolumeInfo& info, const std::string& source) {
  if (const Codec* c = findCodec(info.codec)) return *c;
  throw FormatError(source, "unknown codec id " + std::to_string(std::uint32_t(info.codec)) +
                                " (this build has: " + codecNames() + ")");
}

}  // namespace voxwall::codec
