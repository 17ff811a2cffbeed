// The `raw` codec: a volume stored as raw bricks (raw_bricks.hpp), uncompressed. It is the
// reference every lossy codec is compared with; its options are the format's brick and range
// cell sizes.
#pragma once

#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/kernels/raw_view.hpp>
#include <voxwall/codec/raw_bricks.hpp>

namespace voxwall::codec::raw {

// The codec's registry entry (registry.hpp): the view types its payloads produce, and the codec
// object (src/raw/registration.cpp).
struct RawCodecEntry {
  static constexpr CodecId kId = rawbricks::kCodecId;
  static constexpr std::string_view kName = "raw";
  using Views = ViewList<kernels::RawView<std::uint8_t>, kernels::RawView<std::uint16_t>,
                         kernels::RawView<std::int16_t>, kernels::RawView<float>>;
  static const Codec& instance();
};

}  // namespace voxwall::codec::raw
