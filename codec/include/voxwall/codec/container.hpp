// The .vwz container: one compressed volume, or a time series of them (steps), memory-mappable,
// every byte checksummed.
//
// Layout (little-endian; offsets pinned by static_asserts in container.cpp):
//   offset size  field
//        0    8  magic "VOXWALLZ"
//        8    4  u32 format version (kContainerVersion)
//       12    4  u32 header bytes (128)
//       16    4  u32 codec id (CodecId)
//       20    4  u32 scalar type (ScalarType)
//       24   12  u32 dims x, y, z
//       36    4  u32 section count (<= kMaxSections)
//       40   24  f64 spacing x, y, z
//       64   16  f64 value min, value max
//       80    8  u64 file bytes (the whole file)
//       88    8  u64 xxHash64 (seed 0) of the section table
//       96    4  u32 step count (version 3; zero in versions 1 and 2, read as one step)
//      100   20  reserved, zero
//      120    8  u64 xxHash64 (seed 0) of bytes 0..119
//      128  32n  section table, one entry per section:
//                  u32 section id, u32 step (version 3: the step the section belongs to, or
//                  kSharedStep for a section every step has; zero before), u64 offset,
//                  u64 length, u64 xxHash64
//   then the sections, each starting at a multiple of 64 bytes, in table order, not overlapping.
// Section ids below 0x80000000 are the codec's (each codec documents its own); the container owns
// the ids above:
//   0x80000001  orientation, 96 bytes: f64 direction matrix, column by column (the patient LPS
//               direction of the x, then y, then z axis), then f64 origin x, y, z (millimetres,
//               the centre of voxel 0): see Orientation in volume.hpp.
//   0x80000002  step ranges (version 3, shared), f64 min, max of each step's values, in step
//               order; the header's value range is the whole series'.
// A step's codec sections are its own and the shared ones; the codec sees them as one set, so a
// model every step uses (a dictionary, a codebook) is stored once and each step decodes as a
// volume of its own. One id may not be both a step's own and shared.
// Readers refuse a file whose lengths or offsets do not fit in the file before they touch any
// section data.
// Versions: 1 had no orientation section (read as the identity, LPS); 2 always has one; 3 holds
// steps. A single volume is written as version 2, which earlier builds read; a series as 3.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>
#include <voxwall/codec/volume.hpp>

namespace voxwall::codec {

inline constexpr std::uint32_t kContainerVersion = 3;
inline constexpr std::uint32_t kSingleVolumeVersion = 2;  // what a file of one step is written as
inline constexpr std::uint32_t kContainerSectionIds = 0x80000000u;  // ids from here: container's
inline constexpr std::uint32_t kOrientationSectionId = 0x80000001u;
inline constexpr std::uint32_t kStepRangesSectionId = 0x80000002u;
inline constexpr std::uint32_t kSharedStep = 0xFFFFFFFFu;  // a table entry's step: every step's
inline constexpr std::uint32_t kMaxSections = 1u << 20;
inline constexpr std::uint32_t kMaxSingleVolumeSections = 64;  // versions 1 and 2
inline constexpr std::uint32_t kMaxSteps = 1u << 16;
inline constexpr std::size_t kSectionAlignment = 64;

// The codec id a file stores (header offset 16). Each codec owns its value and name
// (`kId`, `kName` in its registry entry, NAME_codec.hpp); the container knows none of them and
// accepts any id but 0: registry.hpp's `codecOf` says when this build does not carry the codec.
enum class CodecId : std::uint32_t {};

// What the fixed header says about the volume.
struct VolumeInfo {
  CodecId codec{1};
  ScalarType type = ScalarType::UInt8;
  glm::ivec3 dims{0, 0, 0};
  glm::dvec3 spacing{1, 1, 1};
  Orientation orientation{};
  double valueMin = 0, valueMax = 0;  // of the whole series
  int steps = 1;                      // time steps the file holds
  std::size_t voxelCount() const {
    return std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z);
  }
};

// The header description of `volume` (with its orientation) coded with `codec` (what every encoder
// stores).
VolumeInfo volumeInfo(const Volume& volume, CodecId codec);

// Read-only access to a codec's sections by id, wherever they live (a mapped file or memory).
// `source` names the file (or "<memory>") for error messages.
struct SectionSet {
  std::string source;
  std::map<std::uint32_t, std::span<const std::byte>> sections;
  // The section with this id; throws FormatError("<source>: missing section <name>").
  std::span<const std::byte> get(std::uint32_t id, const char* name) const;
};

// A compressed volume held in memory: what an encoder returns and what writeContainer stores.
struct CompressedVolume {
  VolumeInfo info;
  std::vector<std::pair<std::uint32_t, std::vector<std::byte>>> sections;  // (id, bytes)
  SectionSet view(std::string source = "<memory>") const;
  std::uint64_t payloadBytes() const;  // sum of section sizes
};

// A time series of compressed volumes of one size, type, codec and geometry: what a codec's
// encodeSeries returns. Each step's CompressedVolume holds the sections of its own (its info: the
// step's value range); `shared` holds those every step reads.
struct CompressedSeries {
  VolumeInfo info;  // steps and the value range of the whole series
  std::vector<CompressedVolume> steps;
  std::vector<std::pair<std::uint32_t, std::vector<std::byte>>> shared;
  std::uint64_t payloadBytes() const;  // every section, shared ones once
  // Step k as one volume: its sections and the shared ones (copies).
  CompressedVolume step(int k) const;
};
// One series of `steps` (each encoded on its own, of one codec, size, type and geometry; throws
// std::invalid_argument naming the first step that differs), with every section that all steps
// hold with the same id and bytes stored once, shared.
CompressedSeries makeSeries(std::vector<CompressedVolume> steps);

// Serializes to the .vwz layout above (version 2).
std::vector<std::byte> serializeContainer(const CompressedVolume& volume);
// A series: version 3, or version 2 when it has one step.
std::vector<std::byte> serializeContainer(const CompressedSeries& series);
// Writes atomically (temporary file, then rename) and returns the file's size in bytes.
// Throws FormatError on I/O errors.
std::uint64_t writeContainer(const CompressedVolume& volume, const std::string& path);
std::uint64_t writeContainer(const CompressedSeries& series, const std::string& path);

// A .vwz file, memory-mapped and fully validated (header, table, bounds, every checksum) on
// open. Section spans stay valid while the object lives. Move-only.
class ContainerFile {
 public:
  // Throws FormatError("<path>: <what>") for any inconsistency; `path` need not exist as .vwz.
  static ContainerFile open(const std::string& path);
  // Validates bytes already in memory (used by tests and fuzzers); the bytes must outlive it.
  static ContainerFile parse(std::span<const std::byte> bytes, const std::string& source);

  // The series' description: steps, and the value range of every step together.
  const VolumeInfo& info() const { return info_; }
  std::uint32_t version() const { return version_; }  // the file's format version
  // Step 0's sections (the volume's, in a file of one step).
  const SectionSet& sections() const { return steps_.front(); }
  int stepCount() const { return info_.steps; }
  // Step k's sections: its own and the shared ones, as its codec reads them. k in [0, steps).
  const SectionSet& stepSections(int k) const { return steps_.at(std::size_t(k)); }
  // Step k as one volume: info() with one step and the step's own value range.
  VolumeInfo stepInfo(int k) const;
  // Bytes of step k's own sections, and of the shared ones (counted in no step).
  std::uint64_t stepBytes(int k) const { return stepBytes_.at(std::size_t(k)); }
  std::uint64_t sharedBytes() const { return sharedBytes_; }
  std::uint64_t fileBytes() const { return bytes_.size(); }
  const std::string& path() const { return source_; }
  // Drops the mapped file's pages from this process's resident memory (madvise MADV_DONTNEED on
  // the read-only mapping): after the passes that read all of it (open's checksums, a codec's
  // range grid), only what is read again comes back, from the system's page cache, which the
  // ranks on one host share. Spans stay valid. Nothing for parsed bytes.
  void releaseResident() const;
  // Bytes of the mapping resident in this process now (its pages in /proc/self/smaps); 0 for
  // parsed bytes, nullopt where /proc cannot tell.
  std::optional<std::uint64_t> residentMappedBytes() const;

 private:
  struct Mapping;
  std::shared_ptr<Mapping> mapping_;
  std::span<const std::byte> bytes_;
  VolumeInfo info_;
  std::uint32_t version_ = kContainerVersion;
  std::vector<SectionSet> steps_;
  std::vector<std::pair<double, double>> stepRanges_;
  std::vector<std::uint64_t> stepBytes_;
  std::uint64_t sharedBytes_ = 0;
  std::string source_;
};

// True when the file is named *.vwz or starts with the .vwz magic (reads 8 bytes).
bool isContainerFile(const std::string& path);

}  // namespace voxwall::codec
