// A DICOM series' slices (or an enhanced file's frames) placed in the patient, for io/dicom.cpp:
// sorted along their normal, the gaps between them checked (a missing slice, unequal gaps, the
// rounding of the positions the scanner wrote), the slice spacing fitted, and a gantry tilt's
// shear undone or refused.
#pragma once

#include <glm/vec3.hpp>
#include <limits>
#include <string>
#include <vector>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/volume_io.hpp>

namespace voxwall::codec::dicom {

// What the scanner found of one image file, or of one frame of an enhanced multi-frame file.
struct SliceHeader {
  std::string file, series;
  int columns = 0, rows = 0, frames = 1, samples = 1;
  std::vector<double> position, orientation;
  glm::dvec3 ipp{0};
  double along = 0;    // ipp projected on the slice normal
  int frame = -1;      // a frame of an enhanced multi-frame file: which (from 0)
  std::string source;  // a frame: the file that holds it (`file` then names the frame)
  int decimals = 16;   // the digits after the point its Image Position (Patient) was written with
  // What tells the slice's image apart from the series' others (image type, echo, b-value, an
  // enhanced frame's dimension index values, stack and frame type), as a key and in words.
  std::string image, label;
  // What orders slices at one position in time, in this order of precedence (NaN: not given):
  // temporal position, trigger time (ms), acquisition time and content time (s of the day),
  // Instance Number.
  enum TimeKey { kTemporalPosition, kTriggerTime, kAcquisitionTime, kContentTime, kInstance };
  static constexpr int kTimeKeys = 5;
  static constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
  double time[kTimeKeys] = {kNone, kNone, kNone, kNone, kNone};
  // A frame's own Pixel Measures and Pixel Value Transformation (enhanced files).
  std::vector<double> pixelSpacing;  // rows apart, columns apart (mm); empty: not given
  double sliceThickness = 0;
  bool rescaled = false;
  double slope = 1, intercept = 0;
};

// The patient directions of a series' rows, columns and slice normal.
struct SliceAxes {
  glm::dvec3 row{1, 0, 0}, column{0, 1, 0}, normal{0, 0, 1};
};

// Every slice the same size and orientation, at a position of its own along the normal: sorts
// the slices along it (each slice's ipp and along set), checks the gaps between them (equal
// within 1%, or within what rounding the written positions can move them, with a warning through
// options.warn) and returns the series' axes. Throws FormatError naming the file or `name`.
SliceAxes placeSlices(std::vector<SliceHeader>& slices, const std::string& path,
                      const std::string& name, const DicomOptions& options);

// The spacing of sorted slices: the least-squares gap of their positions along the normal.
double fittedGap(const std::vector<SliceHeader>& slices);

// A gantry tilt: each slice's position moves in the slice's plane as well as along its normal.
// Refused unless `resample`, which shifts each slice back onto a box.
void undoGantryTilt(Volume& v, const std::vector<SliceHeader>& slices, const SliceAxes& axes,
                    const std::string& path, const std::string& name, bool resample);

}  // namespace voxwall::codec::dicom
