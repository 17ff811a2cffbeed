// Volume file readers and writers. Formats are chosen from the file name:
//   .nii .nii.gz        NIfTI-1 (nifticlib)
//   .nrrd .nhdr         NRRD, attached or detached header, any teem encoding (teem)
//   .raw (and anything with RawLayout given)  headerless voxels
//   a directory, or a multi-page .tif/.tiff   stack of 2D slices (OpenImageIO)
//   a directory holding DICOM files, a DICOMDIR, or one DICOM file   DICOM (GDCM): docs/dicom.md
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/codec/volume.hpp>

namespace voxwall::codec {

// How a headerless raw file is laid out. Required to read .raw files.
struct RawLayout {
  glm::ivec3 dims{0, 0, 0};
  ScalarType type = ScalarType::UInt8;
  glm::dvec3 spacing{1, 1, 1};
  bool bigEndian = false;
  std::uint64_t headerBytes = 0;  // bytes to skip before the first voxel
  Orientation orientation{};      // where the voxels lie in the patient (identity: LPS)
};

// Which DICOM series to read, and how.
struct DicomOptions {
  std::string series;         // its Series Instance UID; empty: the only series there is
  bool resampleTilt = false;  // resample a gantry-tilted series onto a box instead of refusing it
  // An enhanced multi-frame file that holds several images (echoes, image types, stacks, time
  // points): which one to read, from 1 in the order of their first frames; 0: the only one (a
  // file of several is refused with their list).
  int image = 0;
  // What was read though it was not quite as the standard has it (positions rounded to coarser
  // gaps than 1%), in one line; null: written to standard error as "voxwall: <line>".
  std::function<void(const std::string&)> warn;
};

// What a file does not say about itself: the layout of a raw file, the series of a DICOM folder.
struct ReadOptions {
  std::optional<RawLayout> raw;  // read as a headerless raw file with this layout
  DicomOptions dicom;
  ReadOptions() = default;
  ReadOptions(std::nullopt_t) {}
  ReadOptions(std::optional<RawLayout> layout) : raw(std::move(layout)) {}
  ReadOptions(const RawLayout& layout) : raw(layout) {}
  bool isRaw() const { return raw && raw->dims.x > 0; }
};

enum class VolumeFormat { Raw, Nifti, Nrrd, SliceStack, Dicom };

// Guesses the format from the path (extension; a directory holding DICOM files or a DICOMDIR, or
// a file that starts as DICOM does, is DICOM; any other directory is a stack of slices); throws
// FormatError for an extension we cannot read.
VolumeFormat volumeFormatOf(const std::string& path);

// Reads any supported volume file. `options.raw` is needed (and only used) for raw files,
// `options.dicom` for DICOM. Types other than uint8/uint16/int16/float32 are converted: int8 ->
// int16, int32/uint32/float64 -> float32 (a NIfTI scl_slope other than 1 also gives float32).
// Throws FormatError("<path>: <what>") for unreadable, truncated or unsupported files.
Volume readVolume(const std::string& path, const ReadOptions& options = {});

Volume readRaw(const std::string& path, const RawLayout& layout);
Volume readNifti(const std::string& path);
// A NIfTI file's time steps (dim[4] when it has a fourth dimension, else 1), and one of them.
// readNifti refuses a file of several steps, naming how many.
int niftiStepCount(const std::string& path);
Volume readNiftiStep(const std::string& path, int step);
Volume readNrrd(const std::string& path);
// A NRRD file's time steps: the size of its fourth, slowest axis when that axis is of kind time
// or list (or says no kind) and the first axis is not a single sample, else 1; and one of them.
// readNrrd refuses a file of several steps, naming how many.
int nrrdStepCount(const std::string& path);
Volume readNrrdStep(const std::string& path, int step);
// The time steps of a 4D NIfTI or NRRD file (1 for any other volume file), and one of them.
int volumeStepCount(const std::string& path);
Volume readVolumeStep(const std::string& path, int step);
Volume readSliceStack(const std::string& path);

// A DICOM series: from a folder (searched with its sub-folders), the folder of a DICOMDIR, or one
// (multi-frame) file. Voxels stay in the order DICOM stores them: columns (x), rows (y), then the
// slices sorted by their position along the slice normal. Rescale Slope/Intercept are applied:
// int16 when every slice's rescale is integral and the values fit, float32 otherwise; unscaled
// uint8/uint16/int16 keep their type. Refuses, in one line naming the file or the series: several
// series without `options.series`, several images (echoes, image types, b-values) without
// `options.image`, a time series (DicomInput reads it), slices of different sizes or
// orientations, positions that repeat unequally or that nothing tells apart, a missing slice or
// unequal gaps, a gantry tilt (unless options.resampleTilt), colour images, and files GDCM cannot
// decode.
Volume readDicom(const std::string& path, const DicomOptions& options = {});

// A DICOM series scanned once: the image `options` picks and its time steps, read one at a time.
// A series whose positions repeat, one image (same image type, echo, b-value), is a time series:
// each position's slices ordered by the first of temporal position, trigger time, acquisition
// time, content time and Instance Number that tells all of them apart (an enhanced file's frames
// by their temporal position index or trigger time, then the file's Instance Number and the
// frames' order), step k taking the k-th of each. Throws FormatError as readDicom does.
class DicomInput {
 public:
  DicomInput(const std::string& path, const DicomOptions& options);
  int steps() const;
  // "3 time steps of 48 slices, ordered by instance number"; empty for one step.
  std::string describeSteps() const;
  Volume read(int step) const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

// One image of a DICOM series: what tells it from the others (empty for a series of one), its
// slices a step, its time steps and what ordered them.
struct DicomImageInfo {
  std::string label;
  int slices = 0, steps = 1;
  std::string orderedBy;
};
// The images of the series `options.series` names (or the only one) under `path`.
std::vector<DicomImageInfo> listDicomImages(const std::string& path,
                                            const DicomOptions& options = {});

// One series of a DICOM folder, as listed when the folder holds several.
struct DicomSeriesInfo {
  std::string uid, description, modality;
  int files = 0;
  int columns = 0, rows = 0;
};
// The series under `path` (a folder, a DICOMDIR or one file), in the order of their UIDs.
std::vector<DicomSeriesInfo> listDicomSeries(const std::string& path);

// Writes by extension: .raw (voxels in their own type, x fastest, little endian), .nrrd
// (attached, gzip), .nhdr (+ .raw.gz beside it), .nii or .nii.gz. Writes to a temporary name
// and renames, so a reader never sees half a file. Throws FormatError on I/O errors.
void writeVolume(const Volume& volume, const std::string& path);
void writeRaw(const Volume& volume, const std::string& path);
void writeNrrd(const Volume& volume, const std::string& path);
void writeNifti(const Volume& volume, const std::string& path);
// A series of volumes of one size and type as one 4D NIfTI file (.nii or .nii.gz; dim[4] the
// steps, pixdim[4] = `stepSeconds`).
void writeNiftiSeries(const std::vector<Volume>& steps, const std::string& path,
                      double stepSeconds = 1.0);

}  // namespace voxwall::codec
