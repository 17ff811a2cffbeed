// The zfp codec's view (the byte layout is in zfp_codec.hpp): a CachedBrickView whose decoder
// hands each 16^3 brick's stream to libzfp (zfpDecodeBrick, in src/zfp/layout.cpp), on the host.
// libzfp decodes on the host only (Debian builds it without its CUDA back end, which in zfp 1.0
// decodes fixed-rate streams alone), so a device never gets this view: the payload hands a device
// backend a raw view of the volume decoded once (registration.cpp).
#pragma once

#include <cstdint>
#include <type_traits>
#include <voxwall/codec/kernels/cached_brick_view.hpp>
#include <voxwall/codec/kernels/view_concept.hpp>

namespace voxwall::codec::kernels {

inline constexpr int kZfpBrick = 16;  // voxels per brick side

// zfp's expert parameters (zfp_stream_set_params): together they are the stream's mode.
struct ZfpStreamParams {
  std::uint32_t minbits = 0, maxbits = 0, maxprec = 0;
  std::int32_t minexp = 0;
};

// The codec's half of ZfpView: `index` and `stream` point at the sections in host memory.
struct ZfpDecoder;
// Decodes brick `brick` (bricks x fastest) into out[x + 16 (y + 16 z)] (voxels past the volume's
// edge are 0): the values clamped to [lo, hi] and, for integer types, rounded.
void zfpDecodeBrick(const ZfpDecoder& d, std::uint64_t brick, float* out);

struct ZfpDecoder {
  static constexpr int kBrickSide = kZfpBrick;
  using Value = float;

  const std::uint8_t* index = nullptr;   // the index section (zfp_codec.hpp)
  const std::uint8_t* stream = nullptr;  // the stream section
  std::uint64_t rows = 0;                // rows of bricks along x: bricksY x bricksZ
  int entryBits = 32;                    // the index's bits per brick
  int bricksX = 0, bricksY = 0;
  int dimX = 0, dimY = 0, dimZ = 0;
  std::uint32_t type = 1;  // the volume's ScalarType
  ZfpStreamParams zfp;
  float lo = 0, hi = 0;  // the volume's value range

  // Bricks are not shared: the key is the brick's index.
  VOXWALL_HD_INLINE std::uint64_t key(int bx, int by, int bz) const {
    return (std::uint64_t(bz) * std::uint64_t(bricksY) + std::uint64_t(by)) *
               std::uint64_t(bricksX) +
           std::uint64_t(bx);
  }
  VOXWALL_HD_INLINE void decode(std::uint64_t brick, float* out) const {
#if defined(__CUDA_ARCH__)
    // Unreachable: a device backend is handed a raw view of the decoded volume (above).
    (void)brick, (void)out;
    __trap();
#else
    zfpDecodeBrick(*this, brick, out);
#endif
  }
  VOXWALL_HD_INLINE float scalar(float v) const { return v; }
};

using ZfpView = CachedBrickView<ZfpDecoder>;
static_assert(VolumeView<ZfpView>);

}  // namespace voxwall::codec::kernels
