// Shared by the host and device brick decompressors.
#pragma once

#include <voxwall/codec/ksvd_device.hpp>

namespace voxwall::codec::ksvd {

// Checks that `b` names a brick of the file; returns its level's grid of bricks. Throws
// std::invalid_argument.
glm::ivec3 checkBrick(const Layout& layout, const BrickRef& b);

}  // namespace voxwall::codec::ksvd
