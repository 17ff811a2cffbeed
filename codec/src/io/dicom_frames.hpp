// The frames of an enhanced multi-frame DICOM image (enhanced CT, MR and the other objects with
// functional groups) as their Shared and Per-frame Functional Groups describe them, for
// io/dicom.cpp: where each frame lies, its pixel size and rescale, and which image it belongs to.
#pragma once

#include <limits>
#include <string>
#include <vector>

namespace voxwall::codec::dicom {

struct FrameGeometry {
  // From the frame's own functional group where it has one, else the shared group's; empty where
  // neither says.
  std::vector<double> position;      // Plane Position: Image Position (Patient)
  int positionDecimals = 16;         // the digits after the point it was written with
  std::vector<double> orientation;   // Plane Orientation: Image Orientation (Patient)
  std::vector<double> pixelSpacing;  // Pixel Measures: rows apart, columns apart (mm)
  double sliceThickness = 0;         // Pixel Measures (0: not given)
  bool rescaled = false;             // Pixel Value Transformation given
  double slope = 1, intercept = 0;
  // What tells the frame's image apart from the file's others: its dimension index values other
  // than the in-stack position's and the temporal ones, its stack, frame type, echo time and
  // b-value. Frames of one image have the same `image`; `label` says it in words.
  std::string image, label;
  // Where the frame lies in time (NaN: not given): Temporal Position Index, Trigger Time (ms).
  double temporalIndex = std::numeric_limits<double>::quiet_NaN();
  double triggerTime = std::numeric_limits<double>::quiet_NaN();
};

// The frames of `file`, `frames` of them, from its functional groups; empty when it has no
// Per-frame Functional Groups Sequence (a multi-frame image of the older kind, whose geometry is
// in its top-level attributes). Throws FormatError when the sequence has another number of items
// than the file has frames. Call after checkElements() checked the file.
std::vector<FrameGeometry> enhancedFrames(const std::string& file, int frames);

}  // namespace voxwall::codec::dicom
