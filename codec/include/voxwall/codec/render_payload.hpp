// A compressed volume ready to render: what Codec::open returns and RenderVolume holds. It hands
// the raycaster a view (kernels/view_concept.hpp) over the codec's bytes, wherever they live, and
// the value ranges for empty-space skipping. A device backend uploads bytes() once and asks for
// the view at the device copy; a codec that also wants 3D arrays on the device (SVMM's block
// pools) lists them in deviceArrays() and receives what the backend made of them in deviceView().
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>
#include <voxwall/codec/range_grid.hpp>
#include <voxwall/codec/registry.hpp>

namespace voxwall::codec {

// A 3D array a payload wants on the device: width x height x depth elements of 1, 2 or 4 bytes,
// x fastest. The backend makes it a texture (point sampling, clamp, element type unsigned) when
// the device's 3D texture limits allow, else linear memory in the same layout.
struct DeviceArraySpec {
  std::vector<std::uint8_t> bytes;
  int elementBytes = 1;
  std::size_t width = 0, height = 0, depth = 0;
};
// What the backend made of a DeviceArraySpec: exactly one of the two is set.
struct DeviceArray {
  unsigned long long texture = 0;  // a cudaTextureObject_t
  const std::uint8_t* linear = nullptr;
};

class RenderPayload {
 public:
  virtual ~RenderPayload() = default;
  // Value ranges for empty-space skipping (RangeGrid's contract: dilated by one voxel).
  virtual RangeGrid rangeGrid() const = 0;
  // The bytes the views read: what a device backend uploads.
  virtual std::span<const std::byte> bytes() const = 0;
  // The view with its data at `base` (a copy of bytes(); host memory when null).
  virtual AnyView view(const std::byte* base = nullptr) const = 0;
  // Frees what the host view made on first use to decode blocks (tvq's associated codebooks;
  // nothing by default), which it makes again when a block needs it. Only while no view of this
  // payload is decoding (between frames): the renderer calls it after a frame whose rays read
  // decoded pages only, which then hold the voxels.
  virtual void releaseDecodeTables() const {}
  // 3D arrays for a device backend (none by default), built once per payload.
  virtual std::vector<DeviceArraySpec> deviceArrays() const { return {}; }
  // The device view: bytes() at `base` and the arrays in deviceArrays() order.
  virtual AnyView deviceView(const std::byte* base, std::span<const DeviceArray> arrays) const {
    (void)arrays;
    return view(base);
  }
};

}  // namespace voxwall::codec
