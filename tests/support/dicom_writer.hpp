// Writes DICOM slices and multi-frame files with GDCM, for the tests of the DICOM reader: a CT
// series is made from a phantom in the test, never downloaded.
#pragma once

#include <array>
#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <string>
#include <vector>

namespace voxwall::test {

enum class DicomSyntax { ExplicitLittle, ImplicitLittle, Rle, JpegLs, JpegLossless };

struct DicomSlice {
  int columns = 0, rows = 0;
  std::vector<std::int16_t> pixels;  // columns x rows (x fastest), stored values
  bool isUnsigned = false;           // store them as uint16 (each value must be >= 0)
  int frames = 1;                    // > 1: `pixels` holds every frame, a multi-frame image
  glm::dvec3 position{0, 0, 0};      // Image Position (Patient), mm
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};  // Image Orientation (Patient)
  glm::dvec2 pixelSpacing{1, 1};                        // x (between columns), y (between rows), mm
  double sliceSpacing = 1;          // a multi-frame image's spacing between frames
  double slope = 1, intercept = 0;  // Rescale Slope/Intercept
  std::string seriesUid = "1.2.826.0.1.3680043.2.1125.1";
  std::string description = "phantom";
  int instance = 1;
  DicomSyntax syntax = DicomSyntax::ExplicitLittle;
};

// Writes one DICOM file (CT Image Storage, or Multi-frame Grayscale Word SC for frames > 1,
// which must be unsigned);
// fails the test through an exception when GDCM cannot.
void writeDicom(const std::string& path, const DicomSlice& slice);

}  // namespace voxwall::test
