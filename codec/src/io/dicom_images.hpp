// What one DICOM series holds, for io/dicom.cpp: its slices (files, or the frames of enhanced
// files) split into images (echoes, image types, b-values, stacks: never one volume together)
// and, within an image whose positions repeat, time steps (an fMRI run, a perfusion series,
// cardiac phases, one enhanced file per time point).
#pragma once

#include <optional>
#include <string>
#include <vector>
#include <voxwall/codec/volume_io.hpp>

#include "dicom_slices.hpp"

namespace voxwall::codec::dicom {

struct SeriesImage {
  std::string label;  // what tells it from the series' other images, in words; may be empty
  std::size_t slices = 0;
  // Each step's slices, one a position (unsorted); one step where no position repeats.
  std::vector<std::vector<SliceHeader>> steps;
  std::string orderedBy;  // what ordered the steps: "instance number", "trigger time", ...
};

// What one series holds: its images, or one multi-frame file without functional groups.
struct Contents {
  std::string name, where, unit;  // the series in errors; where its errors start; what a slice is
  std::vector<SeriesImage> images;
  std::optional<SliceHeader> plainMultiFrame;
};

// Splits `slices` into images, numbered in the order of their first slice in `slices`, then each
// image into time steps. Only a series whose positions repeat is split: by each slice's `image`
// key, then in time, ordered at each position by the first of SliceHeader::time that every
// repeat has and no two repeats at one position share. Throws FormatError (naming `path` and
// `name`) when an image's positions repeat unequally or nothing tells two repeats apart.
std::vector<SeriesImage> splitSeries(const std::vector<SliceHeader>& slices,
                                     const std::string& path, const std::string& name);

// The image options.image names (from 1), or the only one; refuses several without it, with
// their list ("holds 2 images in its 18 frames (1: ... (9 frames); ...); read one with
// --dicom-image N"), and a number that names none. `where` starts the error, `unit` counts
// slices ("files", "frames").
const SeriesImage& pickImage(const std::vector<SeriesImage>& images, const DicomOptions& options,
                             const std::string& where, const std::string& unit);

// The images in words: "1: echo time 10 (20 files); 2: echo time 20 (20 files, 3 time steps)".
std::string describeImages(const std::vector<SeriesImage>& images, const std::string& unit);

// Seconds of the day of a DICOM time (TM: HHMMSS.FFFFFF, or the older HH:MM:SS); NaN when the
// text is not one.
double secondsOfDay(const std::string& tm);

}  // namespace voxwall::codec::dicom
