// File helpers private to the codec library (the shared ones are in <voxwall/core/files.hpp>).
#pragma once

#include <string>
#include <voxwall/codec/volume_io.hpp>

namespace voxwall::codec {

// Lower-case file name suffix after the last '.', with ".gz" kept as part of it ("nii.gz").
std::string extensionOf(const std::string& path);

// Refuses a raw file that does not hold exactly the voxels `layout` states (before any is read).
void checkRawFile(const std::string& path, const RawLayout& layout);

// A DICOMDIR, or a file with DICOM's "DICM" after its 128-byte preamble (io/dicom.cpp).
bool isDicomFile(const std::string& path);
// A folder holding such a file (among its first 256 files, sub-folders included).
bool isDicomFolder(const std::string& path);

}  // namespace voxwall::codec
