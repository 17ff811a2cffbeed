// A volume ready to render: a compressed volume (mapped .vwz or made in memory), its views for
// the per-ray code and its coarse value ranges for empty-space skipping.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/volume_io.hpp>

namespace voxwall::node {

// Every view type the raycaster is instantiated for: one or more per registered codec
// (codec/registry.hpp).
using ViewVariant = codec::AnyView;

class RenderVolume {
 public:
  // Opens a .vwz file (memory-mapped) or reads any volume file and bricks it in memory as raw
  // bricks (raw_bricks.hpp). `renderOptions` are the codec's render flags (Codec::renderOptions; a
  // flag the volume's codec does not own is refused with std::invalid_argument). Throws
  // FormatError("<path>: ...").
  static RenderVolume open(const std::string& path, const codec::ReadOptions& options = {},
                           const codec::CodecOptionValues& renderOptions = {});
  // Throws std::invalid_argument ("--progressive needs a .vwz file; <path> is rendered from raw
  // bricks (no codec)") when codec render flags are given for a volume that is not a .vwz file.
  static void refuseRenderOptions(const codec::CodecOptionValues& renderOptions,
                                  const std::string& path);
  static RenderVolume fromContainer(codec::ContainerFile file,
                                    const codec::CodecOptionValues& renderOptions = {});
  // A compressed volume held in memory (any registered codec).
  static RenderVolume fromCompressed(codec::CompressedVolume volume);
  static RenderVolume fromVolume(const codec::Volume& volume,
                                 int brickVoxels = codec::rawbricks::Params{}.brickVoxels);

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
  const codec::RangeGrid& ranges() const { return ranges_; }
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
  // Whether the volume's bytes are a mapped .vwz file (storedBytes() of them: pages the ranks on
  // one host share, and the system drops and reads again) rather than this process's memory.
  bool mapsFile() const { return file_ != nullptr; }
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
  codec::RangeGrid ranges_;
  std::uint64_t storedBytes_ = 0;
  std::string source_;
};

// World-space radius of the volume's bounding sphere (for placing cameras).
double boundingRadius(const codec::VolumeInfo& info);

}  // namespace voxwall::node
