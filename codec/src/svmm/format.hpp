// What the svmm encoder (codec.cpp) and layout (layout.cpp) share: the int16 bias and grid sizes
// per level. The format is documented in svmm_codec.hpp.
#pragma once

#include <algorithm>
#include <cstddef>
#include <glm/vec3.hpp>

namespace voxwall::codec::svmm {

inline constexpr int kInt16Bias = 32768;

inline glm::ivec3 logicalDims(glm::ivec3 dims, int shift) {
  return glm::ivec3(((dims.x - 1) >> shift) + 1, ((dims.y - 1) >> shift) + 1,
                    ((dims.z - 1) >> shift) + 1);
}
inline glm::ivec3 evenUp(glm::ivec3 d) { return (d + 1) / 2 * 2; }
inline std::size_t count3(glm::ivec3 d) {
  return std::size_t(d.x) * std::size_t(d.y) * std::size_t(d.z);
}
inline int maxOf(glm::ivec3 d) { return std::max({d.x, d.y, d.z}); }

}  // namespace voxwall::codec::svmm
