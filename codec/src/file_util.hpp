// File helpers private to the codec library (the shared ones are in <voxwall/core/files.hpp>).
#pragma once

#include <string>

namespace voxwall::codec {

// Lower-case file name suffix after the last '.', with ".gz" kept as part of it ("nii.gz").
std::string extensionOf(const std::string& path);

}  // namespace voxwall::codec
