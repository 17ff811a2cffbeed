// A volume ready to render: a compressed volume (mapped .vwz or made in memory), its views for
// the per-ray code and its coarse value ranges for empty-space skipping.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/codec/volume_io.hpp>

namespace voxwall::node {

// Every view type the raycaster is instantiated for: one or more per registered codec
// (codec/registry.hpp).
using ViewVariant = codec::AnyView;

class RenderVolume {
 public:
  // Opens a .vwz file (memory-mapped) or reads any volume file and bricks it in memory with
  // the raw codec. `renderOptions` are the codec's render flags (Codec::renderOptions; a flag
  // the volume's codec does not own is refused with std::invalid_argument). Throws
  // FormatError("<path>: ...").
  static RenderVolume open(const std::string& path,
                           const std::optional<codec::RawLayout>& raw = std::nullopt,
                           const codec::CodecOptionValues& renderOptions = {});
  static RenderVolume fromContainer(codec::ContainerFile file,
                                    const codec::CodecOptionValues& renderOptions = {});
  // A compressed volume held in memory (any registered codec).
  static RenderVolume fromCompressed(codec::CompressedVolume volume);
  static RenderVolume fromVolume(const codec::Volume& volume,
                                 int brickVoxels = codec::raw::Params{}.brickVoxels);

  const codec::VolumeInfo& info() const { return info_; }
  const codec::RangeGrid& ranges() const { return ranges_; }
  // Bytes of the compressed representation a backend has to hold (file size for a .vwz).
  std::uint64_t storedBytes() const { return storedBytes_; }
  // The codec's render payload: the bytes a device backend uploads, the view with its data at a
  // base address (host memory when null), the arrays a device builds (render_payload.hpp).
  const codec::RenderPayload& payload() const { return *payload_; }
  ViewVariant view(const std::byte* base = nullptr) const { return payload_->view(base); }
  // Whether the view traverses mip levels (--lod, nearest sampling).
  bool traversal() const;
  const std::string& source() const { return source_; }
  // xxHash64 of the volume's description and every section's bytes: two ranks with the same
  // fingerprint render the same pixels. Computed on first use (reads the whole payload).
  std::uint64_t fingerprint() const;
  // Drops the mapped .vwz file from this process's resident memory after the passes that read
  // all of it (opening, the range grid, the fingerprint): a rank then holds only the compressed
  // bytes its rays read (codec::ContainerFile::releaseResident). Nothing for a volume in memory.
  void releaseMappedPages() const {
    if (file_) file_->releaseResident();
  }

 private:
  RenderVolume() = default;
  void init(const codec::CodecOptionValues& renderOptions = {});
  std::shared_ptr<codec::ContainerFile> file_;
  std::shared_ptr<codec::CompressedVolume> memory_;
  codec::SectionSet sections_;
  // Validated once, in init(); points into file_ or memory_ (declared after them: destroyed first).
  std::shared_ptr<const codec::RenderPayload> payload_;
  codec::VolumeInfo info_;
  codec::RangeGrid ranges_;
  std::uint64_t storedBytes_ = 0;
  std::string source_;
};

// World-space radius of the volume's bounding sphere (for placing cameras).
double boundingRadius(const codec::VolumeInfo& info);

}  // namespace voxwall::node
