// File helpers private to the codec library (the public ones are in <voxwall/codec/files.hpp>).
#pragma once

#include <string>
#include <voxwall/codec/files.hpp>

namespace voxwall::codec {

// fsync()s a finished file; throws FormatError naming `path` (the file it will become).
void syncFile(const std::string& file, const std::string& path);

// Lower-case file name suffix after the last '.', with ".gz" kept as part of it ("nii.gz").
std::string extensionOf(const std::string& path);

}  // namespace voxwall::codec
