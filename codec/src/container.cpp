// The .vwz container; layout in container.hpp.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <voxwall/codec/container.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>

#include "file_util.hpp"

namespace voxwall::codec {
namespace {

constexpr char kMagic[8] = {'V', 'O', 'X', 'W', 'A', 'L', 'L', 'Z'};
// Field offsets of the fixed header, pinned so a change to the writer is deliberate.
constexpr std::size_t kOffVersion = 8, kOffHeaderBytes = 12, kOffCodec = 16, kOffType = 20,
                      kOffDims = 24, kOffSectionCount = 36, kOffSpacing = 40, kOffRange = 64,
                      kOffFileBytes = 80, kOffTableHash = 88, kOffReserved = 96,
                      kOffHeaderHash = 120, kHeaderBytes = 128, kTableEntryBytes = 32;
static_assert(sizeof kMagic == kOffVersion);
static_assert(kOffVersion + 4 == kOffHeaderBytes);
static_assert(kOffHeaderBytes + 4 == kOffCodec);
static_assert(kOffCodec + 4 == kOffType);
static_assert(kOffType + 4 == kOffDims);
static_assert(kOffDims + 3 * 4 == kOffSectionCount);
static_assert(kOffSectionCount + 4 == kOffSpacing);
static_assert(kOffSpacing + 3 * 8 == kOffRange);
static_assert(kOffRange + 2 * 8 == kOffFileBytes);
static_assert(kOffFileBytes + 8 == kOffTableHash);
static_assert(kOffTableHash + 8 == kOffReserved);
static_assert(kOffReserved + 24 == kOffHeaderHash);
static_assert(kOffHeaderHash + 8 == kHeaderBytes);

std::uint64_t hashBytes(std::span<const std::byte> bytes) {
  return XXH64(bytes.data(), bytes.size(), 0);
}

// Fuzz builds (libFuzzer's convention) let corrupt checksums through so the fuzzer reaches the
// parsers behind them; every other check stays.
constexpr bool kVerifyChecksums =
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
    false;
#else
    true;
#endif

std::size_t alignUp(std::size_t n) {
  return (n + kSectionAlignment - 1) / kSectionAlignment * kSectionAlignment;
}

}  // namespace

VolumeInfo volumeInfo(const Volume& volume, CodecId codec) {
  VolumeInfo info;
  info.codec = codec;
  info.type = volume.type;
  info.dims = volume.dims;
  info.spacing = volume.spacing;
  info.orientation = volume.orientation;
  info.valueMin = volume.valueMin;
  info.valueMax = volume.valueMax;
  return info;
}

std::span<const std::byte> SectionSet::get(std::uint32_t id, const char* name) const {
  auto it = sections.find(id);
  if (it == sections.end())
    throw FormatError(
        source, std::string("missing section '") + name + "' (id " + std::to_string(id) + ")");
  return it->second;
}

SectionSet CompressedVolume::view(std::string source) const {
  SectionSet set;
  set.source = std::move(source);
  for (auto& [id, bytes] : sections) set.sections[id] = bytes;
  return set;
}

std::uint64_t CompressedVolume::payloadBytes() const {
  std::uint64_t n = 0;
  for (auto& s : sections) n += s.second.size();
  return n;
}

namespace {

constexpr std::size_t kOrientationBytes = 12 * 8;

std::vector<std::byte> orientationSection(const Orientation& o) {
  std::vector<std::byte> out;
  ByteWriter w(out);
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) w.put<double>(o.direction[c][r]);
  for (int i = 0; i < 3; ++i) w.put<double>(o.origin[i]);
  return out;
}

Orientation parseOrientation(std::span<const std::byte> bytes, const std::string& source) {
  if (bytes.size() != kOrientationBytes)
    throw FormatError(source, "orientation section has " + std::to_string(bytes.size()) +
                                  " bytes, not " + std::to_string(kOrientationBytes));
  ByteReader r(bytes, source, "orientation section");
  Orientation o;
  for (int c = 0; c < 3; ++c)
    for (int row = 0; row < 3; ++row) o.direction[c][row] = r.get<double>();
  for (int i = 0; i < 3; ++i) o.origin[i] = r.get<double>();
  if (const std::string problem = orientationProblem(o.direction); !problem.empty())
    throw FormatError(source, "invalid orientation: " + problem);
  if (!std::isfinite(o.origin.x) || !std::isfinite(o.origin.y) || !std::isfinite(o.origin.z))
    throw FormatError(source, "invalid orientation: its origin is not finite");
  return o;
}

// One section as the writer lays it out: its id, its step (kSharedStep: every step's), its bytes.
struct TableEntry {
  std::uint32_t id = 0, step = 0;
  std::span<const std::byte> bytes;
};

// The header and section table of a file, and where each section starts. `sections` are the
// codec's followed by the container's own (orientation; step ranges in a series).
struct ContainerHead {
  std::vector<std::byte> bytes;
  std::vector<std::byte> orientation, stepRanges;
  std::vector<TableEntry> sections;
  std::vector<std::size_t> offsets;
  std::size_t fileBytes = 0;
};

void checkCodecId(std::uint32_t id) {
  if (id >= kContainerSectionIds)
    throw std::invalid_argument("section id " + std::to_string(id) +
                                " is one of the container's own");
}

// `ranges`: each step's value range (a series, version 3), or empty (one volume, version 2).
ContainerHead containerHead(const VolumeInfo& info, std::vector<TableEntry> entries,
                            const std::vector<std::pair<double, double>>& ranges) {
  const bool series = !ranges.empty();
  if (entries.size() + 2 > kMaxSections)
    throw std::invalid_argument("too many sections for a .vwz file");
  if (series && (ranges.size() > kMaxSteps))
    throw std::invalid_argument("too many steps for a .vwz file (at most " +
                                std::to_string(kMaxSteps) + ")");
  ContainerHead head;
  head.orientation = orientationSection(info.orientation);
  for (const TableEntry& e : entries) checkCodecId(e.id);
  head.sections = std::move(entries);
  head.sections.push_back({kOrientationSectionId, kSharedStep, head.orientation});
  if (series) {
    ByteWriter r(head.stepRanges);
    for (const auto& [lo, hi] : ranges) r.put<double>(lo), r.put<double>(hi);
    head.sections.push_back({kStepRangesSectionId, kSharedStep, head.stepRanges});
  }
  // Lay out the sections first so the header can state the file size.
  std::size_t end = alignUp(kHeaderBytes + kTableEntryBytes * head.sections.size());
  for (auto& s : head.sections) {
    head.offsets.push_back(end);
    end = alignUp(end + s.bytes.size());
  }
  head.fileBytes = head.offsets.back() + head.sections.back().bytes.size();

  std::vector<std::byte>& out = head.bytes;
  ByteWriter w(out);
  w.putBytes(std::as_bytes(std::span(kMagic)));
  w.put<std::uint32_t>(series ? kContainerVersion : kSingleVolumeVersion);
  w.put<std::uint32_t>(kHeaderBytes);
  w.put<std::uint32_t>(std::uint32_t(info.codec));
  w.put<std::uint32_t>(std::uint32_t(info.type));
  for (int i = 0; i < 3; ++i) w.put<std::uint32_t>(std::uint32_t(info.dims[i]));
  w.put<std::uint32_t>(std::uint32_t(head.sections.size()));
  for (int i = 0; i < 3; ++i) w.put<double>(info.spacing[i]);
  w.put<double>(info.valueMin);
  w.put<double>(info.valueMax);
  w.put<std::uint64_t>(head.fileBytes);
  // The table comes after the header but its hash sits in it: write the table aside first.
  std::vector<std::byte> table;
  ByteWriter tw(table);
  for (std::size_t i = 0; i < head.sections.size(); ++i) {
    const TableEntry& e = head.sections[i];
    tw.put<std::uint32_t>(e.id);
    tw.put<std::uint32_t>(series ? e.step : 0);
    tw.put<std::uint64_t>(head.offsets[i]);
    tw.put<std::uint64_t>(e.bytes.size());
    tw.put<std::uint64_t>(hashBytes(e.bytes));
  }
  w.put<std::uint64_t>(hashBytes(table));
  w.put<std::uint32_t>(series ? std::uint32_t(ranges.size()) : 0);
  w.put<std::uint32_t>(0);
  for (int i = 0; i < 2; ++i) w.put<std::uint64_t>(0);
  w.put<std::uint64_t>(hashBytes(std::span(out).first(kOffHeaderHash)));
  w.putBytes(table);
  return head;
}

ContainerHead containerHead(const CompressedVolume& volume) {
  std::vector<TableEntry> entries;
  for (const auto& [id, bytes] : volume.sections) entries.push_back({id, 0, bytes});
  return containerHead(volume.info, std::move(entries), {});
}

ContainerHead containerHead(const CompressedSeries& series) {
  if (series.steps.empty()) throw std::invalid_argument("a series of no steps");
  if (series.steps.size() == 1 && series.shared.empty()) return containerHead(series.steps.front());
  std::vector<TableEntry> entries;
  for (const auto& [id, bytes] : series.shared) entries.push_back({id, kSharedStep, bytes});
  std::vector<std::pair<double, double>> ranges;
  for (std::size_t k = 0; k < series.steps.size(); ++k) {
    for (const auto& [id, bytes] : series.steps[k].sections)
      entries.push_back({id, std::uint32_t(k), bytes});
    ranges.emplace_back(series.steps[k].info.valueMin, series.steps[k].info.valueMax);
  }
  VolumeInfo info = series.info;
  info.valueMin = ranges.front().first, info.valueMax = ranges.front().second;
  for (const auto& [lo, hi] : ranges)
    info.valueMin = std::min(info.valueMin, lo), info.valueMax = std::max(info.valueMax, hi);
  return containerHead(info, std::move(entries), ranges);
}

std::vector<std::byte> serialize(const ContainerHead& head) {
  std::vector<std::byte> out = head.bytes;
  out.reserve(head.fileBytes);
  for (std::size_t i = 0; i < head.sections.size(); ++i) {
    out.resize(head.offsets[i]);
    out.insert(out.end(), head.sections[i].bytes.begin(), head.sections[i].bytes.end());
  }
  out.resize(head.fileBytes);
  return out;
}

std::uint64_t write(const ContainerHead& head, const std::string& path) {
  // Piece by piece from the sections themselves: a joined copy of the file would double the
  // memory `compress` needs for its output.
  static constexpr std::byte kZeros[kSectionAlignment] = {};
  std::vector<std::span<const std::byte>> pieces{head.bytes};
  std::size_t at = head.bytes.size();
  for (std::size_t i = 0; i < head.sections.size(); ++i) {
    pieces.emplace_back(kZeros, head.offsets[i] - at);
    pieces.emplace_back(head.sections[i].bytes);
    at = head.offsets[i] + head.sections[i].bytes.size();
  }
  commitTemporary(writeTemporary(path, pieces), path);
  return head.fileBytes;
}

}  // namespace

std::uint64_t CompressedSeries::payloadBytes() const {
  std::uint64_t n = 0;
  for (const auto& s : shared) n += s.second.size();
  for (const auto& s : steps) n += s.payloadBytes();
  return n;
}

CompressedVolume CompressedSeries::step(int k) const {
  CompressedVolume v = steps.at(std::size_t(k));
  v.sections.insert(v.sections.begin(), shared.begin(), shared.end());
  return v;
}

CompressedSeries makeSeries(std::vector<CompressedVolume> steps) {
  if (steps.empty()) throw std::invalid_argument("a series of no steps");
  CompressedSeries series;
  series.info = steps.front().info;
  series.info.steps = int(steps.size());
  for (std::size_t k = 1; k < steps.size(); ++k) {
    const VolumeInfo& a = steps.front().info;
    const VolumeInfo& b = steps[k].info;
    if (a.codec != b.codec || a.type != b.type || a.dims != b.dims || a.spacing != b.spacing ||
        a.orientation.direction != b.orientation.direction ||
        a.orientation.origin != b.orientation.origin)
      throw std::invalid_argument("step " + std::to_string(k) +
                                  " differs from step 0 in codec, size, type or geometry");
    series.info.valueMin = std::min(series.info.valueMin, b.valueMin);
    series.info.valueMax = std::max(series.info.valueMax, b.valueMax);
  }
  // A section every step has with the same bytes is stored once.
  if (steps.size() > 1)
    for (std::size_t i = 0; i < steps.front().sections.size();) {
      const std::uint32_t id = steps.front().sections[i].first;
      const std::vector<std::byte>& bytes = steps.front().sections[i].second;
      bool everywhere = true;
      for (std::size_t k = 1; k < steps.size() && everywhere; ++k) {
        const auto& other = steps[k].sections;
        everywhere = std::any_of(other.begin(), other.end(),
                                 [&](const auto& s) { return s.first == id && s.second == bytes; });
      }
      if (!everywhere) {
        ++i;
        continue;
      }
      series.shared.emplace_back(id, bytes);
      for (auto& step : steps)
        std::erase_if(step.sections, [id](const auto& s) { return s.first == id; });
    }
  series.steps = std::move(steps);
  return series;
}

std::vector<std::byte> serializeContainer(const CompressedVolume& volume) {
  return serialize(containerHead(volume));
}

std::vector<std::byte> serializeContainer(const CompressedSeries& series) {
  return serialize(containerHead(series));
}

std::uint64_t writeContainer(const CompressedVolume& volume, const std::string& path) {
  return write(containerHead(volume), path);
}

std::uint64_t writeContainer(const CompressedSeries& series, const std::string& path) {
  return write(containerHead(series), path);
}

struct ContainerFile::Mapping {
  void* address = nullptr;
  std::size_t length = 0;
  ~Mapping() {
    if (address) munmap(address, length);
  }
};

ContainerFile ContainerFile::open(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw FormatError(path, std::strerror(errno));
  struct stat st {};
  if (fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    throw FormatError(path, std::strerror(err));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw FormatError(path, "not a regular file");
  }
  auto mapping = std::make_shared<Mapping>();
  mapping->length = std::size_t(st.st_size);
  if (mapping->length > 0) {
    mapping->address = mmap(nullptr, mapping->length, PROT_READ, MAP_PRIVATE, fd, 0);
    if (mapping->address == MAP_FAILED) {
      mapping->address = nullptr;
      const int err = errno;
      ::close(fd);
      throw FormatError(path, std::string("cannot map file: ") + std::strerror(err));
    }
  }
  ::close(fd);
  auto bytes = std::span(static_cast<const std::byte*>(mapping->address), mapping->length);
  ContainerFile file = parse(bytes, path);
  file.mapping_ = std::move(mapping);
  return file;
}

void ContainerFile::releaseResident() const {
  if (mapping_ && mapping_->address) madvise(mapping_->address, mapping_->length, MADV_DONTNEED);
}

std::optional<std::uint64_t> ContainerFile::residentMappedBytes() const {
  if (!mapping_ || !mapping_->address) return 0;
  std::ifstream smaps("/proc/self/smaps");
  if (!smaps) return std::nullopt;
  const auto begin = reinterpret_cast<std::uintptr_t>(mapping_->address);
  const std::uintptr_t end = begin + mapping_->length;
  // An area's header ("lo-hi perms ..."), then its fields; the mapping may have been split
  // into several areas.
  std::uint64_t kib = 0;
  bool inside = false, seen = false;
  std::string line;
  while (std::getline(smaps, line)) {
    unsigned long long lo = 0;
    char space = 0;
    if (std::sscanf(line.c_str(), "%llx-%*x%c", &lo, &space) == 2 && space == ' ') {
      inside = lo >= begin && lo < end;  // (an area ends on a page boundary)
      seen = seen || inside;
      continue;
    }
    unsigned long long n = 0;
    if (inside && std::sscanf(line.c_str(), "Rss: %llu kB", &n) == 1) kib += n;
  }
  if (!seen) return std::nullopt;
  return kib * 1024;
}

namespace {

// What the fixed header says beyond the volume's description: the format version, the section
// table (it lies in the file: its size is bounded by the file's) and the steps.
struct Header {
  std::uint32_t version = 1, sectionCount = 0, steps = 1;
  std::size_t tableEnd = 0;
  std::span<const std::byte> table;
};

// The volume's description in the header (codec, scalar type, dims, spacing, value range) into
// `info`, and the section count among them.
void readDescription(ByteReader& r, const std::string& source, std::uint32_t version,
                     VolumeInfo& info, std::uint32_t& sectionCount) {
  auto fail = [&](const std::string& what) -> void { throw FormatError(source, what); };
  const auto codec = r.get<std::uint32_t>();
  if (codec == 0) fail("codec id 0 (no codec has it)");
  info.codec = CodecId(codec);
  const auto type = r.get<std::uint32_t>();
  if (type < 1 || type > 4) fail("unknown scalar type " + std::to_string(type));
  info.type = ScalarType(type);
  for (int i = 0; i < 3; ++i) {
    const auto d = r.get<std::uint32_t>();
    if (d == 0 || d > (1u << 24)) fail("invalid dimension " + std::to_string(d));
    info.dims[i] = int(d);
  }
  checkDims(info.dims, source);
  sectionCount = r.get<std::uint32_t>();
  if (sectionCount > (version >= 3 ? kMaxSections : kMaxSingleVolumeSections))
    fail("section count " + std::to_string(sectionCount) + " is too large");
  for (int i = 0; i < 3; ++i) {
    info.spacing[i] = r.get<double>();
    if (!(info.spacing[i] > 0) || !std::isfinite(info.spacing[i])) fail("invalid voxel spacing");
  }
  info.valueMin = r.get<double>();
  info.valueMax = r.get<double>();
  if (!std::isfinite(info.valueMin) || !std::isfinite(info.valueMax) ||
      info.valueMin > info.valueMax)
    fail("invalid value range");
}

// The header: its checks, its checksums and the table's, the volume's description into `info`.
Header readHeader(std::span<const std::byte> bytes, const std::string& source, VolumeInfo& info) {
  auto fail = [&](const std::string& what) -> void { throw FormatError(source, what); };
  if (bytes.size() < kHeaderBytes)
    fail("not a .vwz file: " + std::to_string(bytes.size()) + " bytes is shorter than the " +
         std::to_string(kHeaderBytes) + "-byte header");
  if (std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) fail("not a .vwz file (bad magic)");
  ByteReader r(bytes.first(kHeaderBytes), source, "header");
  r.skip(8);
  Header h;
  h.version = r.get<std::uint32_t>();
  if (h.version < 1 || h.version > kContainerVersion)
    fail("unsupported .vwz format version " + std::to_string(h.version) +
         " (this build reads 1 to " + std::to_string(kContainerVersion) + ")");
  const auto headerBytes = r.get<std::uint32_t>();
  if (headerBytes != kHeaderBytes) fail("header size " + std::to_string(headerBytes) + " is wrong");
  ByteReader hashReader(bytes.subspan(kOffHeaderHash, 8), source, "header");
  if (kVerifyChecksums && hashBytes(bytes.first(kOffHeaderHash)) != hashReader.get<std::uint64_t>())
    fail("header checksum mismatch (the file is corrupt)");
  readDescription(r, source, h.version, info, h.sectionCount);
  const auto fileBytes = r.get<std::uint64_t>();
  if (fileBytes != bytes.size())
    fail("file is " + std::to_string(bytes.size()) + " bytes but its header says " +
         std::to_string(fileBytes) + (fileBytes > bytes.size() ? " (truncated)" : ""));
  h.tableEnd = kHeaderBytes + kTableEntryBytes * h.sectionCount;
  if (h.tableEnd > bytes.size()) fail("section table runs past the end of the file (truncated)");
  h.table = bytes.subspan(kHeaderBytes, h.tableEnd - kHeaderBytes);
  const std::uint64_t storedTableHash = r.get<std::uint64_t>();
  if (kVerifyChecksums && hashBytes(h.table) != storedTableHash)
    fail("section table checksum mismatch (the file is corrupt)");
  if (h.version >= 3) {
    h.steps = r.get<std::uint32_t>();
    if (h.steps < 1 || h.steps > kMaxSteps)
      fail("step count " + std::to_string(h.steps) + " is not 1 to " + std::to_string(kMaxSteps));
  }
  info.steps = int(h.steps);
  return h;
}

// A codec's section as the table lists it.
struct Entry {
  std::uint32_t id, step;
  std::span<const std::byte> data;
  std::string name;
};
// The table: the codecs' sections in order, and the container's own (orientation, step ranges).
struct Table {
  std::vector<Entry> entries;
  std::span<const std::byte> orientation, stepRanges;
};

Table readTable(std::span<const std::byte> bytes, const std::string& source, const Header& h) {
  auto fail = [&](const std::string& what) -> void { throw FormatError(source, what); };
  Table out;
  ByteReader t(h.table, source, "section table");
  std::uint64_t previousEnd = h.tableEnd;
  for (std::uint32_t i = 0; i < h.sectionCount; ++i) {
    const auto id = t.get<std::uint32_t>();
    const auto step = h.version >= 3 ? t.get<std::uint32_t>() : (t.skip(4), 0u);
    const auto offset = t.get<std::uint64_t>();
    const auto length = t.get<std::uint64_t>();
    const auto hash = t.get<std::uint64_t>();
    std::string name = "section " + std::to_string(i) + " (id " + std::to_string(id) +
                       (h.steps == 1          ? std::string()
                        : step == kSharedStep ? std::string(", shared by every step")
                                              : ", step " + std::to_string(step)) +
                       ")";
    if (offset % kSectionAlignment)
      fail(name + ": offset " + std::to_string(offset) + " is not 64-byte aligned");
    if (offset < previousEnd) fail(name + ": overlaps the table or the previous section");
    if (offset > bytes.size() || length > bytes.size() - offset)
      fail(name + ": " + std::to_string(length) + " bytes at offset " + std::to_string(offset) +
           " run past the end of the file (truncated)");
    auto data = bytes.subspan(offset, length);
    if (kVerifyChecksums && hashBytes(data) != hash)
      fail(name + ": checksum mismatch (the file is corrupt)");
    if (step != kSharedStep && step >= h.steps)
      fail(name + ": step " + std::to_string(step) + " is past the file's " +
           std::to_string(h.steps) + " step(s)");
    previousEnd = offset + length;
    if (id < kContainerSectionIds) {
      out.entries.push_back({id, step, data, std::move(name)});
      continue;
    }
    std::span<const std::byte>* known =
        id == kOrientationSectionId && h.version >= 2  ? &out.orientation
        : id == kStepRangesSectionId && h.version >= 3 ? &out.stepRanges
                                                       : nullptr;
    if (!known)
      fail("section id " + std::to_string(id) + " is reserved for the container and unknown");
    if (step != (h.version >= 3 ? kSharedStep : 0u))
      fail(name + ": the container's own section belongs to no step");
    if (!known->empty() || known->data()) fail(name + ": duplicate section id");
    *known = data;
  }
  return out;
}

// Each step's value range (a version 3 file's section; the file's range before).
std::vector<std::pair<double, double>> readStepRanges(std::span<const std::byte> stepRanges,
                                                      const std::string& source, const Header& h,
                                                      const VolumeInfo& info) {
  if (h.version < 3) return {{info.valueMin, info.valueMax}};
  if (stepRanges.size() != 16 * std::size_t(h.steps))
    throw FormatError(source, "the step ranges section has " + std::to_string(stepRanges.size()) +
                                  " bytes, not 16 for each of " + std::to_string(h.steps) +
                                  " step(s)");
  std::vector<std::pair<double, double>> out;
  ByteReader sr(stepRanges, source, "step ranges");
  for (std::uint32_t k = 0; k < h.steps; ++k) {
    const double lo = sr.get<double>(), hi = sr.get<double>();
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi || lo < info.valueMin ||
        hi > info.valueMax)
      throw FormatError(source, "step " + std::to_string(k) +
                                    ": its value range is not finite or lies outside the file's");
    out.emplace_back(lo, hi);
  }
  return out;
}

}  // namespace

ContainerFile ContainerFile::parse(std::span<const std::byte> bytes, const std::string& source) {
  ContainerFile file;
  file.bytes_ = bytes;
  file.source_ = source;
  auto fail = [&](const std::string& what) -> void { throw FormatError(source, what); };
  const Header h = readHeader(bytes, source, file.info_);
  file.version_ = h.version;
  const Table table = readTable(bytes, source, h);
  // Version 1 files predate orientation: their voxels are taken as LPS, as they were rendered.
  if (h.version >= 2) {
    if (!table.orientation.data()) fail("the orientation section is missing");
    file.info_.orientation = parseOrientation(table.orientation, source);
  }
  file.stepRanges_ = readStepRanges(table.stepRanges, source, h, file.info_);
  file.steps_.assign(h.steps, SectionSet{source, {}});
  file.stepBytes_.assign(h.steps, 0);
  for (const Entry& e : table.entries) {
    if (e.step == kSharedStep) continue;
    if (!file.steps_[e.step].sections.emplace(e.id, e.data).second)
      fail(e.name + ": duplicate section id");
    file.stepBytes_[e.step] += e.data.size();
  }
  const auto shared = std::count_if(table.entries.begin(), table.entries.end(),
                                    [](const Entry& e) { return e.step == kSharedStep; });
  if (shared > std::ptrdiff_t(kMaxSingleVolumeSections))
    fail(std::to_string(shared) + " shared sections: at most " +
         std::to_string(kMaxSingleVolumeSections));
  for (const Entry& e : table.entries) {
    if (e.step != kSharedStep) continue;
    file.sharedBytes_ += e.data.size();
    for (std::uint32_t k = 0; k < h.steps; ++k)
      if (!file.steps_[k].sections.emplace(e.id, e.data).second)
        fail(e.name + ": step " + std::to_string(k) + " has a section of the same id");
  }
  return file;
}

VolumeInfo ContainerFile::stepInfo(int k) const {
  VolumeInfo info = info_;
  info.steps = 1;
  info.valueMin = stepRanges_.at(std::size_t(k)).first;
  info.valueMax = stepRanges_.at(std::size_t(k)).second;
  return info;
}

bool isContainerFile(const std::string& path) {
  // By name too, so a truncated or unreadable .vwz gets the container's own error message.
  if (path.size() > 4 && path.ends_with(".vwz")) return true;
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  if (!in.read(magic, 8)) return false;
  return std::memcmp(magic, kMagic, 8) == 0;
}

}  // namespace voxwall::codec
