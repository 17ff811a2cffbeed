// What the tvq encoder (codec.cpp) and layout (layout.cpp) share: section sizes, bounds and the
// block grid. The byte layout itself is documented in tvq_codec.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/common.hpp>
#include <glm/vec3.hpp>
#include <vector>
#include <voxwall/codec/tvq_codec.hpp>

namespace voxwall::codec::tvq {

inline constexpr std::size_t kParamsBytes = 88;
inline constexpr std::size_t kSubvolumeBytes = 112;
inline constexpr int kMaxCodeBitsTotal = 3 * kMaxCodeBits;
inline constexpr double kMaxScale = 1e30;
// SubPlan::cls of a ZERO block equal to its sub-volume's background: it gets no record.
inline constexpr std::uint8_t kUncoded = 255;

// The coefficients (k >= 1) of partition p that a class's chapter holds, in coefficient order.
inline std::vector<int> chapterCoefficients(const Basis& basis, int p, int cls) {
  std::vector<int> out;
  const std::uint8_t keep = classZones(cls);
  for (int k = 1; k < kBlockVoxels; ++k) {
    const int z = basis.zone[std::size_t(k)];
    if (zonePartition(z) == p && (keep & (1u << z))) out.push_back(k);
  }
  return out;
}

// The block grid and its sub-volumes.
struct Grid {
  glm::ivec3 dims{}, blocks{}, subs{};
  int s = 64;
  Grid(glm::ivec3 d, int subBlocks) : dims(d), s(subBlocks) {
    blocks = (dims + 3) / 4;
    subs = (blocks + s - 1) / s;
  }
  std::uint64_t subCount() const {
    return std::uint64_t(subs.x) * std::uint64_t(subs.y) * std::uint64_t(subs.z);
  }
  glm::ivec3 subCoords(std::uint64_t i) const {
    return {int(i % std::uint64_t(subs.x)), int(i / std::uint64_t(subs.x) % std::uint64_t(subs.y)),
            int(i / (std::uint64_t(subs.x) * std::uint64_t(subs.y)))};
  }
  glm::ivec3 first(std::uint64_t i) const { return subCoords(i) * s; }
  glm::ivec3 extent(std::uint64_t i) const { return glm::min(glm::ivec3(s), blocks - first(i)); }
  static std::uint64_t volume(glm::ivec3 e) {
    return std::uint64_t(e.x) * std::uint64_t(e.y) * std::uint64_t(e.z);
  }
};

}  // namespace voxwall::codec::tvq
