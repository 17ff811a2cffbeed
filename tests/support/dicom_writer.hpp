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
  // >= 0: Image Position (Patient) written with this many digits after the point (a scanner's
  // rounding), trailing zeros dropped; -1: as GDCM writes the double.
  int positionDecimals = -1;
  std::string modality = "CT";  // a single frame: CT or MR (GDCM picks the SOP class from it)
  // What tells repeats at one position apart, written when not empty, 0 or negative.
  std::string imageType;        // Image Type (0008,0008)
  int echoNumber = 0;           // Echo Numbers (0018,0086)
  double echoTime = -1;         // Echo Time (0018,0081), ms
  double bValue = -1;           // Diffusion b-value (0018,9087)
  double triggerTime = -1;      // Trigger Time (0018,1060), ms
  int temporalPosition = 0;     // Temporal Position Identifier (0020,0100)
  std::string acquisitionTime;  // Acquisition Time (0008,0032): HHMMSS.FFFFFF
};

// Writes one DICOM file (CT Image Storage, or Multi-frame Grayscale Word SC for frames > 1,
// which must be unsigned);
// fails the test through an exception when GDCM cannot.
void writeDicom(const std::string& path, const DicomSlice& slice);

// One frame of an enhanced multi-frame image: where it lies and what it is, in its own
// (per-frame) functional groups.
struct EnhancedFrame {
  glm::dvec3 position{0, 0, 0};      // Plane Position: Image Position (Patient), mm
  std::vector<std::int16_t> pixels;  // columns x rows (x fastest), stored values
  double slope = 1, intercept = 0;   // Pixel Value Transformation
  std::string frameType = "ORIGINAL\\PRIMARY\\M_FFE\\M_FFE";  // MR/CT Image Frame Type
  std::uint32_t imageIndex = 1;     // first Dimension Index Value (the image, e.g. its type)
  std::uint32_t stackPosition = 1;  // second: In-Stack Position Number
  std::string stackId = "1";
  std::uint32_t temporalIndex = 0;  // Frame Content's Temporal Position Index; 0: not written
  double triggerTime = -1;          // Cardiac Synchronization's Nominal Cardiac Trigger Delay Time
};

// An enhanced CT or MR image (Enhanced CT/MR Image Storage): geometry in the Shared (orientation,
// pixel measures) and Per-frame (position, rescale, frame type, frame content) Functional Groups
// only, none of it at the top level, where a misleading Pixel Spacing of 1 mm is written.
struct EnhancedImage {
  std::string modality = "MR";  // MR or CT
  int columns = 0, rows = 0;
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};
  glm::dvec2 pixelSpacing{1, 1};  // x (between columns), y (between rows), mm
  double sliceThickness = 1;
  std::vector<EnhancedFrame> frames;
  bool dimensionIndex = true;  // write the Dimension Index Sequence (image, in-stack position)
  std::string seriesUid = "1.2.826.0.1.3680043.2.1125.7";
  int instance = 1;  // Instance Number (also makes the SOP Instance UID)
};
void writeEnhancedDicom(const std::string& path, const EnhancedImage& image);

}  // namespace voxwall::test
