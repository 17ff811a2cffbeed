// The .vwz container; layout in container.hpp.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <cerrno>
#include <cmath>
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

// The header and section table of `volume`'s file, and where each section starts. `sections`
// are the codec's followed by the container's own orientation section.
struct ContainerHead {
  std::vector<std::byte> bytes;
  std::vector<std::byte> orientation;
  std::vector<std::pair<std::uint32_t, std::span<const std::byte>>> sections;
  std::vector<std::size_t> offsets;
  std::size_t fileBytes = 0;
};

ContainerHead containerHead(const CompressedVolume& volume) {
  if (volume.sections.size() + 1 > kMaxSections)
    throw std::invalid_argument("too many sections for a .vwz file");
  ContainerHead head;
  head.orientation = orientationSection(volume.info.orientation);
  for (auto& [id, bytes] : volume.sections) {
    if (id >= kContainerSectionIds)
      throw std::invalid_argument("section id " + std::to_string(id) +
                                  " is one of the container's own");
    head.sections.emplace_back(id, bytes);
  }
  head.sections.emplace_back(kOrientationSectionId, head.orientation);
  // Lay out the sections first so the header can state the file size.
  std::size_t end = alignUp(kHeaderBytes + kTableEntryBytes * head.sections.size());
  for (auto& s : head.sections) {
    head.offsets.push_back(end);
    end = alignUp(end + s.second.size());
  }
  head.fileBytes = head.offsets.back() + head.sections.back().second.size();

  std::vector<std::byte>& out = head.bytes;
  ByteWriter w(out);
  w.putBytes(std::as_bytes(std::span(kMagic)));
  w.put<std::uint32_t>(kContainerVersion);
  w.put<std::uint32_t>(kHeaderBytes);
  w.put<std::uint32_t>(std::uint32_t(volume.info.codec));
  w.put<std::uint32_t>(std::uint32_t(volume.info.type));
  for (int i = 0; i < 3; ++i) w.put<std::uint32_t>(std::uint32_t(volume.info.dims[i]));
  w.put<std::uint32_t>(std::uint32_t(head.sections.size()));
  for (int i = 0; i < 3; ++i) w.put<double>(volume.info.spacing[i]);
  w.put<double>(volume.info.valueMin);
  w.put<double>(volume.info.valueMax);
  w.put<std::uint64_t>(head.fileBytes);
  // The table comes after the header but its hash sits in it: write the table aside first.
  std::vector<std::byte> table;
  ByteWriter tw(table);
  for (std::size_t i = 0; i < head.sections.size(); ++i) {
    auto& [id, bytes] = head.sections[i];
    tw.put<std::uint32_t>(id);
    tw.put<std::uint32_t>(0);
    tw.put<std::uint64_t>(head.offsets[i]);
    tw.put<std::uint64_t>(bytes.size());
    tw.put<std::uint64_t>(hashBytes(bytes));
  }
  w.put<std::uint64_t>(hashBytes(table));
  for (int i = 0; i < 3; ++i) w.put<std::uint64_t>(0);
  w.put<std::uint64_t>(hashBytes(std::span(out).first(kOffHeaderHash)));
  w.putBytes(table);
  return head;
}

}  // namespace

std::vector<std::byte> serializeContainer(const CompressedVolume& volume) {
  ContainerHead head = containerHead(volume);
  std::vector<std::byte> out = std::move(head.bytes);
  out.reserve(head.fileBytes);
  for (std::size_t i = 0; i < head.sections.size(); ++i) {
    out.resize(head.offsets[i]);
    out.insert(out.end(), head.sections[i].second.begin(), head.sections[i].second.end());
  }
  out.resize(head.fileBytes);
  return out;
}

std::uint64_t writeContainer(const CompressedVolume& volume, const std::string& path) {
  // Piece by piece from the sections themselves: a joined copy of the file would double the
  // memory `compress` needs for its output.
  const ContainerHead head = containerHead(volume);
  static constexpr std::byte kZeros[kSectionAlignment] = {};
  std::vector<std::span<const std::byte>> pieces{head.bytes};
  std::size_t at = head.bytes.size();
  for (std::size_t i = 0; i < head.sections.size(); ++i) {
    pieces.emplace_back(kZeros, head.offsets[i] - at);
    pieces.emplace_back(head.sections[i].second);
    at = head.offsets[i] + head.sections[i].second.size();
  }
  commitTemporary(writeTemporary(path, pieces), path);
  return head.fileBytes;
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

ContainerFile ContainerFile::parse(std::span<const std::byte> bytes, const std::string& source) {
  ContainerFile file;
  file.bytes_ = bytes;
  file.sections_.source = source;
  auto fail = [&](const std::string& what) -> void { throw FormatError(source, what); };
  if (bytes.size() < kHeaderBytes)
    fail("not a .vwz file: " + std::to_string(bytes.size()) + " bytes is shorter than the " +
         std::to_string(kHeaderBytes) + "-byte header");
  if (std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) fail("not a .vwz file (bad magic)");
  ByteReader r(bytes.first(kHeaderBytes), source, "header");
  r.skip(8);
  const auto version = r.get<std::uint32_t>();
  if (version < 1 || version > kContainerVersion)
    fail("unsupported .vwz format version " + std::to_string(version) + " (this build reads 1 to " +
         std::to_string(kContainerVersion) + ")");
  file.version_ = version;
  const auto headerBytes = r.get<std::uint32_t>();
  if (headerBytes != kHeaderBytes) fail("header size " + std::to_string(headerBytes) + " is wrong");
  const auto storedHeaderHash = [&] {
    ByteReader h(bytes.subspan(kOffHeaderHash, 8), source, "header");
    return h.get<std::uint64_t>();
  }();
  if (kVerifyChecksums && hashBytes(bytes.first(kOffHeaderHash)) != storedHeaderHash)
    fail("header checksum mismatch (the file is corrupt)");

  VolumeInfo& info = file.info_;
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
  const auto sectionCount = r.get<std::uint32_t>();
  if (sectionCount > kMaxSections)
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
  const auto fileBytes = r.get<std::uint64_t>();
  if (fileBytes != bytes.size())
    fail("file is " + std::to_string(bytes.size()) + " bytes but its header says " +
         std::to_string(fileBytes) + (fileBytes > bytes.size() ? " (truncated)" : ""));

  const std::size_t tableEnd = kHeaderBytes + kTableEntryBytes * sectionCount;
  if (tableEnd > bytes.size()) fail("section table runs past the end of the file (truncated)");
  const auto table = bytes.subspan(kHeaderBytes, tableEnd - kHeaderBytes);
  const std::uint64_t storedTableHash = r.get<std::uint64_t>();
  if (kVerifyChecksums && hashBytes(table) != storedTableHash)
    fail("section table checksum mismatch (the file is corrupt)");
  ByteReader t(table, source, "section table");
  std::uint64_t previousEnd = tableEnd;
  for (std::uint32_t i = 0; i < sectionCount; ++i) {
    const auto id = t.get<std::uint32_t>();
    t.skip(4);
    const auto offset = t.get<std::uint64_t>();
    const auto length = t.get<std::uint64_t>();
    const auto hash = t.get<std::uint64_t>();
    const std::string name = "section " + std::to_string(i) + " (id " + std::to_string(id) + ")";
    if (offset % kSectionAlignment)
      fail(name + ": offset " + std::to_string(offset) + " is not 64-byte aligned");
    if (offset < previousEnd) fail(name + ": overlaps the table or the previous section");
    if (offset > bytes.size() || length > bytes.size() - offset)
      fail(name + ": " + std::to_string(length) + " bytes at offset " + std::to_string(offset) +
           " run past the end of the file (truncated)");
    auto data = bytes.subspan(offset, length);
    if (kVerifyChecksums && hashBytes(data) != hash)
      fail(name + ": checksum mismatch (the file is corrupt)");
    if (!file.sections_.sections.emplace(id, data).second) fail(name + ": duplicate section id");
    previousEnd = offset + length;
  }
  // Version 1 files predate orientation: their voxels are taken as LPS, as they were rendered.
  auto& sections = file.sections_.sections;
  if (version >= 2) {
    const auto it = sections.find(kOrientationSectionId);
    if (it == sections.end()) fail("the orientation section is missing");
    info.orientation = parseOrientation(it->second, source);
    sections.erase(it);
  }
  for (const auto& [id, data] : sections)
    if (id >= kContainerSectionIds)
      fail("section id " + std::to_string(id) + " is reserved for the container and unknown");
  return file;
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
