// Shared by the host and device brick decompressors.
#pragma once

#include <voxwall/codec/ksvd_device.hpp>

namespace voxwall::codec::ksvd {

// Checks that `b` names a brick of the file. Throws std::invalid_argument.
void checkBrick(const Layout& layout, const BrickRef& b);

}  // namespace voxwall::codec::ksvd
