// A volume ready to render: a compressed volume (mapped .vwz or made in memory), its views for
// the per-ray code and its coarse value ranges for empty-space skipping.
#pragma once

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/volume_io.hpp>

namespace voxwall::node {

// Every view type the raycaster is instantiated for: one or more per registered codec
// (codec/registry.hpp).
using ViewVariant = codec::AnyView;

// The codec's value ranges (codec::RangeGrid) held in the volume's own scalar type: two values a
// cell of the type's size instead of two floats (uint8: 2 bytes a 4^3 cell instead of 8, about
// 88 MiB less per rank at 0.95 Gvox). Integer types round outwards (floor the low end, ceil the
// high end, clamped to the type, whose values are all an integer codec's decoder gives); a NaN
// end widens to the type's whole range. A wider range only skips less, never a visible sample.
class CellRanges {
 public:
  CellRanges() = default;
  CellRanges(const codec::RangeGrid& grid, codec::ScalarType type);

  int cellVoxels() const { return cellVoxels_; }
  glm::ivec3 cells() const { return cells_; }
  std::size_t cellCount() const {
    return std::size_t(cells_.x) * std::size_t(cells_.y) * std::size_t(cells_.z);
  }
  std::size_t bytes() const { return bytes_.size(); }
  // f(cell, lo, hi) for every cell, x fastest.
  template <class F>
  void forEach(F&& f) const {
    codec::dispatchScalar(type_, [&]<class T>(T) {
      const std::size_t n = cellCount();
      for (std::size_t c = 0; c < n; ++c) {
        T pair[2];
        std::memcpy(pair, bytes_.data() + c * sizeof pair, sizeof pair);
        f(c, float(pair[0]), float(pair[1]));
      }
    });
  }

 private:
  int cellVoxels_ = 8;
  glm::ivec3 cells_{0, 0, 0};
  codec::ScalarType type_ = codec::ScalarType::Float32;
  std::vector<std::byte> bytes_;  // per cell: lo, hi in type_
};

class RenderVolume {
 public:
  // Opens a .vwz file (memory-mapped) or reads any volume file and bricks it in memory with
  // the raw codec. `renderOptions` are the codec's render flags (Codec::renderOptions; a flag
  // the volume's codec does not own is refused with std::invalid_argument). Throws
  // FormatError("<path>: ...").
  static RenderVolume open(const std::string& path, const codec::ReadOptions& options = {},
                           const codec::CodecOptionValues& renderOptions = {});
  // Throws std::invalid_argument ("--progressive needs a .vwz file; <path> is rendered with the
  // raw codec") when codec render flags are given for a volume that is not a .vwz file.
  static void refuseRenderOptions(const codec::CodecOptionValues& renderOptions,
                                  const std::string& path);
  static RenderVolume fromContainer(codec::ContainerFile file,
                                    const codec::CodecOptionValues& renderOptions = {});
  // A compressed volume held in memory (any registered codec).
  static RenderVolume fromCompressed(codec::CompressedVolume volume);
  static RenderVolume fromVolume(const codec::Volume& volume,
                                 int brickVoxels = codec::raw::Params{}.brickVoxels);

  // The volume's description; for a time series, the whole series' (steps, the range of every
  // step together), whichever step this is.
  const codec::VolumeInfo& info() const { return info_; }
  // Time steps: how many the file holds, which one this is, and another one of them (opened
  // from the same mapped file with the same render flags: its own payload and ranges). Throws
  // std::invalid_argument for a step outside 0..steps()-1, FormatError as open() does.
  int steps() const { return info_.steps; }
  int step() const { return step_; }
  RenderVolume atStep(int step) const;
  // The value range of step k's own voxels (of the volume, for one step).
  std::pair<double, double> stepRange(int k) const;
  const CellRanges& ranges() const { return ranges_; }
  // Bytes of the compressed representation a backend has to hold (file size for a .vwz).
  std::uint64_t storedBytes() const { return storedBytes_; }
  // The codec's render payload: the bytes a device backend uploads, the view with its data at a
  // base address (host memory when null), the arrays a device builds (render_payload.hpp).
  const codec::RenderPayload& payload() const { return *payload_; }
  ViewVariant view(const std::byte* base = nullptr) const { return payload_->view(base); }
  // Unique to the payload in this process, never reused (an address may be, once a step's
  // payload is let go and the next one allocated): what a device backend keys its uploads by.
  std::uint64_t payloadId() const { return payloadId_; }
  // Whether the view traverses mip levels (--lod, nearest sampling).
  bool traversal() const;
  // The volume decoded whole by its codec and bricked like a raw volume, made on the first call
  // and kept (host memory about 1.2x the voxels'; the decode itself briefly holds the voxels
  // once more): what a device backend samples at raw speed instead of decoding blocks per ray.
  // Null where it cannot stand in for payload(): a raw volume, a time series or codec render
  // flags (--progressive); nor can it for frames that sample mip levels (RayFrame::nearest,
  // lodAngle). Thread-safe.
  const codec::RenderPayload* decodedPayload() const;
  std::uint64_t decodedPayloadId() const;  // as payloadId(), for decodedPayload()
  // The bytes decodedPayload()'s bricks take, from the volume's size (0 where there is none).
  std::uint64_t decodedBytes() const;
  const std::string& source() const { return source_; }
  // xxHash64 of the volume's description and every section's bytes (of every step): two ranks
  // with the same fingerprint render the same pixels. Reads the whole file.
  std::uint64_t fingerprint() const;
  // Drops the mapped .vwz file from this process's resident memory
  // (codec::ContainerFile::releaseResident) after the passes that read all of it (opening, the
  // range grid, the fingerprint). Nothing for a volume in memory.
  void releaseMappedPages() const {
    if (file_) file_->releaseResident();
  }
  // After a frame whose rays read decoded pages (node/page_cache.hpp) that all fit in the
  // budget: what only decoding reads goes, the mapped file's pages and the tables the codec made
  // to decode (RenderPayload::releaseDecodeTables), since the pages now hold the voxels; a later
  // decode takes them back (the file from the system's page cache). Only between frames.
  void releaseDecodeSources() const {
    releaseMappedPages();
    payload_->releaseDecodeTables();
  }
  // Bytes of the mapped .vwz resident in this process (0 for a volume in memory; nullopt where
  // the system cannot tell).
  std::optional<std::uint64_t> mappedResidentBytes() const {
    return file_ ? file_->residentMappedBytes() : std::optional<std::uint64_t>(0);
  }

 private:
  RenderVolume() = default;
  void init(const codec::CodecOptionValues& renderOptions = {});
  std::shared_ptr<codec::ContainerFile> file_;
  codec::CodecOptionValues renderOptions_;
  int step_ = 0;
  std::shared_ptr<codec::CompressedVolume> memory_;
  codec::SectionSet sections_;
  // Validated once, in init(); points into file_ or memory_ (declared after them: destroyed first).
  std::shared_ptr<const codec::RenderPayload> payload_;
  std::uint64_t payloadId_ = 0;
  struct Decoded;
  std::shared_ptr<Decoded> decoded_;  // null: no decodedPayload()
  codec::VolumeInfo info_;
  CellRanges ranges_;
  std::uint64_t storedBytes_ = 0;
  std::string source_;
};

// World-space radius of the volume's bounding sphere (for placing cameras).
double boundingRadius(const codec::VolumeInfo& info);

}  // namespace voxwall::node
