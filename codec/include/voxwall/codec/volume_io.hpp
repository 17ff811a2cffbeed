// Volume file readers and writers. Formats are chosen from the file name:
//   .nii .nii.gz        NIfTI-1 (nifticlib)
//   .nrrd .nhdr         NRRD, attached or detached header, any teem encoding (teem)
//   .raw (and anything with RawLayout given)  headerless voxels
//   a directory, or a multi-page .tif/.tiff   stack of 2D slices (OpenImageIO)
#pragma once

#include <optional>
#include <string>
#include <voxwall/codec/volume.hpp>

namespace voxwall::codec {

// How a headerless raw file is laid out. Required to read .raw files.
struct RawLayout {
  glm::ivec3 dims{0, 0, 0};
  ScalarType type = ScalarType::UInt8;
  glm::dvec3 spacing{1, 1, 1};
  bool bigEndian = false;
  std::uint64_t headerBytes = 0;  // bytes to skip before the first voxel
};

enum class VolumeFormat { Raw, Nifti, Nrrd, SliceStack };

// Guesses the format from the path (extension, or a directory for slices); throws FormatError
// for an extension we cannot read.
VolumeFormat volumeFormatOf(const std::string& path);

// Reads any supported volume file. `raw` is needed (and only used) for raw files.
// Types other than uint8/uint16/int16/float32 are converted: int8 -> int16,
// int32/uint32/float64 -> float32 (a NIfTI scl_slope other than 1 also gives float32).
// Throws FormatError("<path>: <what>") for unreadable, truncated or unsupported files.
Volume readVolume(const std::string& path, const std::optional<RawLayout>& raw = std::nullopt);

Volume readRaw(const std::string& path, const RawLayout& layout);
Volume readNifti(const std::string& path);
Volume readNrrd(const std::string& path);
Volume readSliceStack(const std::string& path);

// Writes by extension: .raw (voxels in their own type, x fastest, little endian), .nrrd
// (attached, gzip), .nhdr (+ .raw.gz beside it), .nii or .nii.gz. Writes to a temporary name
// and renames, so a reader never sees half a file. Throws FormatError on I/O errors.
void writeVolume(const Volume& volume, const std::string& path);
void writeRaw(const Volume& volume, const std::string& path);
void writeNrrd(const Volume& volume, const std::string& path);
void writeNifti(const Volume& volume, const std::string& path);

}  // namespace voxwall::codec
