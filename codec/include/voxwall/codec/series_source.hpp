// A time series of volumes read one step at a time: a 4D NIfTI or NRRD file, a DICOM series
// whose positions repeat in time (DicomInput), a file
// pattern ("sim_%04d.nrrd": every file in its folder the pattern prints, in the order of their
// numbers), a list of 3D files, or a raw file holding several volumes one after the other. Every
// step must agree with step 0 on size, type and spacing; the first that does not is named in one
// line.
#pragma once

#include <memory>
#include <string>
#include <vector>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec {

// What names the steps besides the input path.
struct SeriesInput {
  std::vector<std::string> files;  // the steps' files, in order (`--time-files`)
  int rawSteps = 0;                // a raw file of this many volumes (`--time N`; with --dims)
};

class SeriesSource {
 public:
  // Where a step's voxels are: a file of its own, or one volume of a 4D NIfTI or NRRD file, of
  // a raw file of several volumes (read with the ReadOptions' raw layout) or of a DICOM series.
  enum class Kind { File, FileVolume, RawVolume, DicomStep };
  struct Step {
    std::string name;  // "sim_0003.nrrd", or "fmri.nii.gz step 3"
    std::string file;  // the file it is read from
    int index = 0;     // the volume's index in that file
    Kind kind = Kind::File;
  };

  // `dicom`: the scanned series DicomStep steps are read from.
  SeriesSource(std::vector<Step> steps, ReadOptions options,
               std::shared_ptr<const DicomInput> dicom = nullptr);
  int steps() const { return int(steps_.size()); }
  const std::string& stepName(int k) const { return steps_.at(std::size_t(k)).name; }
  // Step k, read in slabs where the format allows (volume_source.hpp), else whole. Throws
  // FormatError("<step's file>: step k ... but step 0 ...") when it differs from step 0 in size,
  // type or spacing (step 0 is read for its header first when it was not opened yet).
  std::unique_ptr<VolumeSource> open(int k, Progress& progress) const;

 private:
  std::unique_ptr<VolumeSource> read(int k, Progress& progress) const;
  std::vector<Step> steps_;
  ReadOptions options_;
  std::shared_ptr<const DicomInput> dicom_;
  mutable bool haveFirst_ = false;
  mutable glm::ivec3 dims_{0};
  mutable ScalarType type_ = ScalarType::UInt8;
  mutable glm::dvec3 spacing_{1.0};
};

// Whether `path` is a file pattern: it holds a printf integer conversion (%d, %04d, %3d).
bool isStepPattern(const std::string& path);
// The series `path` and `input` name, or null when they name one volume: a NIfTI file or DICOM
// series of one step, any other file, no --time-files and no --time. Throws FormatError for a
// pattern no file matches and std::invalid_argument for inputs that contradict each other.
std::unique_ptr<SeriesSource> openSeries(const std::string& path, const ReadOptions& options,
                                         const SeriesInput& input);

}  // namespace voxwall::codec
