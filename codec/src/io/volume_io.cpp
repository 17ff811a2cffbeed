#include <filesystem>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {

VolumeFormat volumeFormatOf(const std::string& path) {
  if (std::filesystem::is_directory(path))
    return isDicomFolder(path) ? VolumeFormat::Dicom : VolumeFormat::SliceStack;
  const std::string ext = extensionOf(path);
  if (ext == "nii" || ext == "nii.gz") return VolumeFormat::Nifti;
  if (ext == "nrrd" || ext == "nhdr") return VolumeFormat::Nrrd;
  if (ext == "raw" || ext == "raw.gz" || ext == "bin" || ext == "dat") return VolumeFormat::Raw;
  if (ext == "tif" || ext == "tiff") return VolumeFormat::SliceStack;
  if (ext == "dcm" || ext == "dicom" || isDicomFile(path)) return VolumeFormat::Dicom;
  throw FormatError(path, "unknown volume format '." + ext +
                              "' (expected .nii, .nii.gz, .nrrd, .nhdr, .raw, .tif/.tiff, a "
                              "DICOM file or DICOMDIR, or a folder of slices or of DICOM files)");
}

namespace {

Volume readAnyVolume(const std::string& path, const ReadOptions& options) {
  // Raw dimensions given on the command line mean "read this as raw", whatever the name.
  if (options.isRaw()) return readRaw(path, *options.raw);
  switch (volumeFormatOf(path)) {
    case VolumeFormat::Raw:
      throw FormatError(path, "raw files need their dimensions and type (--dims X,Y,Z --type T)");
    case VolumeFormat::Nifti:
      return readNifti(path);
    case VolumeFormat::Nrrd:
      return readNrrd(path);
    case VolumeFormat::SliceStack:
      return readSliceStack(path);
    case VolumeFormat::Dicom:
      return readDicom(path, options.dicom);
  }
  throw FormatError(path, "unknown volume format");
}

}  // namespace

int volumeStepCount(const std::string& path) {
  if (std::filesystem::is_directory(path)) return 1;
  switch (volumeFormatOf(path)) {
    case VolumeFormat::Nifti:
      return niftiStepCount(path);
    case VolumeFormat::Nrrd:
      return nrrdStepCount(path);
    default:
      return 1;
  }
}

Volume readVolumeStep(const std::string& path, int step) {
  return volumeFormatOf(path) == VolumeFormat::Nrrd ? readNrrdStep(path, step)
                                                    : readNiftiStep(path, step);
}

Volume readVolume(const std::string& path, const ReadOptions& options) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory)
    throw FormatError(path, "cannot read: " + ec.message());
  if (!std::filesystem::exists(status)) throw FormatError(path, "no such file or directory");
  try {
    return readAnyVolume(path, options);
  } catch (const std::bad_alloc&) {
    throw FormatError(path, "not enough memory to read it");
  } catch (const std::filesystem::filesystem_error& e) {
    throw FormatError(path, "cannot read: " + e.code().message());
  }
}

void writeVolume(const Volume& volume, const std::string& path) {
  const std::string ext = extensionOf(path);
  if (ext == "raw") return writeRaw(volume, path);
  if (ext == "nrrd" || ext == "nhdr") return writeNrrd(volume, path);
  if (ext == "nii" || ext == "nii.gz") return writeNifti(volume, path);
  throw FormatError(path,
                    "cannot write '." + ext + "' (expected .raw, .nrrd, .nhdr, .nii or .nii.gz)");
}

}  // namespace voxwall::codec
