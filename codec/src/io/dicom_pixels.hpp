// A DICOM image's pixels through GDCM, for io/dicom.cpp: each file checked before GDCM reads it
// (dicom_checks.hpp), decoded (any transfer syntax Debian's GDCM decodes), and a series' slices
// or an image's frames rescaled into one volume of the smallest type that holds their values.
#pragma once

#include <gdcmPixelFormat.h>

#include <cstddef>
#include <glm/vec3.hpp>
#include <string>
#include <vector>
#include <voxwall/codec/volume.hpp>

#include "dicom_slices.hpp"

namespace voxwall::codec::dicom {

// The volume's stored values before rescaling, one type for the whole series.
enum class Stored { U8, I8, U16, I16, U32, I32 };
Stored storedOf(const gdcm::PixelFormat& pf, const std::string& file);
std::size_t storedBytes(Stored s);

// One decoded image (a slice, or every frame of a multi-frame file) written to `out`.
struct Decoded {
  Stored stored;
  double slope = 1, intercept = 0;
  glm::dvec3 spacing{1, 1, 1};
  unsigned dims[3] = {1, 1, 1};
  double cosines[6] = {1, 0, 0, 0, 1, 0};  // GDCM's direction cosines (row, then column)
  double origin[3] = {0, 0, 0};            // and origin (the first frame's position)
};

// The orientation of an image from its row and column direction cosines and its position: the
// identity when the cosines are not two perpendicular unit vectors.
Orientation orientationOf(const double* cosines, const double* position);

// Decodes `file` into `buffer` at `offset`; `expectBytes` (0: any) is the size the series' first
// slice had. Throws FormatError naming the file.
Decoded decode(const std::string& file, std::vector<std::byte>& buffer, std::size_t offset,
               std::size_t expectBytes);

// The stored values of every slice rescaled into a volume of the smallest type that holds them.
Volume rescaled(std::vector<std::byte> stored, Stored type, glm::ivec3 dims, glm::dvec3 spacing,
                const std::vector<Decoded>& slices);

// A multi-frame file without functional groups: its frames in stored order, GDCM's spacing and
// orientation.
Volume readMultiFrame(const SliceHeader& h);

// The slices' pixels, decoded in slice order into `stored`, each checked against the header's
// size and the first slice's type: single-frame files, or frames of enhanced files (each file
// decoded once, each frame with its own rescale).
std::vector<Decoded> decodeSlices(const std::vector<SliceHeader>& slices, glm::ivec3 dims,
                                  std::vector<std::byte>& stored);

}  // namespace voxwall::codec::dicom
