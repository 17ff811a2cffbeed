// A volume ready to render: a compressed volume (mapped .vwz or made in memory), its views for
// the per-ray code and its coarse value ranges for empty-space skipping.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/kernels/raw_view.hpp>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/vq_codec.hpp>

namespace voxwall::node {

// Every view type the raycaster is instantiated for (one per codec and scalar type).
using ViewVariant =
    std::variant<codec::kernels::RawView<std::uint8_t>, codec::kernels::RawView<std::uint16_t>,
                 codec::kernels::RawView<std::int16_t>, codec::kernels::RawView<float>,
                 codec::kernels::VqView, codec::kernels::SvmmView>;

class RenderVolume {
 public:
  // Opens a .vwz file (memory-mapped) or reads any volume file and bricks it in memory with
  // the raw codec. Throws FormatError("<path>: ...").
  static RenderVolume open(const std::string& path,
                           const std::optional<codec::RawLayout>& raw = std::nullopt);
  static RenderVolume fromContainer(codec::ContainerFile file);
  static RenderVolume fromVolume(const codec::Volume& volume,
                                 int brickVoxels = codec::raw::Params{}.brickVoxels);

  const codec::VolumeInfo& info() const { return info_; }
  const codec::RangeGrid& ranges() const { return ranges_; }
  // Bytes of the compressed representation a backend has to hold (file size for a .vwz).
  std::uint64_t storedBytes() const { return storedBytes_; }
  // The voxel payload a device backend uploads, and the view with its data at `base`
  // (host memory when null).
  std::span<const std::byte> payload() const;
  ViewVariant view(const std::byte* base = nullptr) const;
  const std::string& source() const { return source_; }
  // The svmm layout when the volume is svmm-coded (a device backend builds block pools from it).
  const codec::svmm::Layout* svmmLayout() const { return svmmLayout_ ? &*svmmLayout_ : nullptr; }
  // xxHash64 of the volume's description and every section's bytes: two ranks with the same
  // fingerprint render the same pixels. Computed on first use (reads the whole payload).
  std::uint64_t fingerprint() const;

 private:
  RenderVolume() = default;
  void init();
  std::shared_ptr<codec::ContainerFile> file_;
  std::shared_ptr<codec::CompressedVolume> memory_;
  codec::SectionSet sections_;
  std::optional<codec::raw::Layout> rawLayout_;  // validated once, in init()
  std::optional<codec::vq::Layout> vqLayout_;
  std::optional<codec::svmm::Layout> svmmLayout_;
  codec::VolumeInfo info_;
  codec::RangeGrid ranges_;
  std::uint64_t storedBytes_ = 0;
  std::string source_;
};

// World-space radius of the volume's bounding sphere (for placing cameras).
double boundingRadius(const codec::VolumeInfo& info);

}  // namespace voxwall::node
