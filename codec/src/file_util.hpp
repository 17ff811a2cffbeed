// File helpers private to the codec library.
#pragma once

#include <cstddef>
#include <span>
#include <string>

namespace voxwall::codec {

// Writes `bytes` to "<path>.tmp.<pid>" and renames it over `path`, so readers never see half a
// file. Throws FormatError naming `path` on any I/O error.
void writeFileAtomically(const std::string& path, std::span<const std::byte> bytes);

// Renames a finished temporary file over `path` (or removes it and throws on failure).
void commitTemporary(const std::string& temporary, const std::string& path);
std::string temporaryNameFor(const std::string& path);

// Lower-case file name suffix after the last '.', with ".gz" kept as part of it ("nii.gz").
std::string extensionOf(const std::string& path);

}  // namespace voxwall::codec
