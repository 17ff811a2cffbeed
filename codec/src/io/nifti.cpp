// NIfTI-1 through nifticlib. Voxels keep file order; the sform (else the qform) becomes the
// volume's Orientation, converted from NIfTI's RAS to voxwall's LPS.
#include <nifti1_io.h>
#include <zlib.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <glm/geometric.hpp>
#include <memory>
#include <optional>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {
namespace {

struct NiftiDeleter {
  void operator()(nifti_image* nim) const { nifti_image_free(nim); }
};
using NiftiPtr = std::unique_ptr<nifti_image, NiftiDeleter>;

template <class Src, class Dst>
void convert(const void* src, Volume& v, double slope, double inter) {
  const Src* s = static_cast<const Src*>(src);
  auto d = v.as<Dst>();
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = Dst(double(s[i]) * slope + inter);
}

// Decompresses a whole gzip stream and returns its length; throws when the stream is truncated
// or corrupt. nifticlib reads a truncated .nii.gz without complaint, so we check first.
std::uint64_t gzipLength(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw FormatError(path, "cannot open");
  std::vector<char> buffer(1 << 20);
  std::uint64_t total = 0;
  for (;;) {
    const int n = gzread(f, buffer.data(), unsigned(buffer.size()));
    if (n < 0) {
      int code = 0;
      const std::string message = gzerror(f, &code);
      gzclose_r(f);
      throw FormatError(path, "corrupt gzip stream: " + message);
    }
    if (n == 0) break;
    total += std::uint64_t(n);
  }
  // gzread stops quietly at a truncated end; gzclose_r then reports Z_BUF_ERROR.
  const int closed = gzclose_r(f);
  if (closed != Z_OK) throw FormatError(path, "truncated or corrupt gzip stream");
  return total;
}

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

// The fields nifticlib converts without complaint: where the voxels start and the spacings.
// `have` is the size of the (uncompressed) file.
void checkRawHeader(const std::string& path, std::uint64_t have) {
  int swapped = 0;
  std::unique_ptr<nifti_1_header, void (*)(void*)> raw(nifti_read_header(path.c_str(), &swapped, 0),
                                                       &std::free);
  if (!raw) return;  // a NIfTI-2 file: nifticlib checked what it read
  const double offset = raw->vox_offset;
  const bool singleFile = std::strncmp(raw->magic, "n+1", 3) == 0;
  if (!std::isfinite(offset) || offset < 0)
    throw FormatError(path, "vox_offset " + number(offset) + " is not a byte offset");
  if (singleFile && offset < double(sizeof(nifti_1_header)))
    throw FormatError(path, "vox_offset " + number(offset) + " lies inside the " +
                                std::to_string(sizeof(nifti_1_header)) + "-byte header");
  if (singleFile && offset > double(have))
    throw FormatError(path, "vox_offset " + number(offset) + " lies past the end of the file (" +
                                std::to_string(have) + " bytes)");
  for (int i = 1; i <= 3; ++i)
    if (!std::isfinite(raw->pixdim[i]) || raw->pixdim[i] < 0)
      throw FormatError(path, "pixdim[" + std::to_string(i) + "] = " + number(raw->pixdim[i]) +
                                  " is not a voxel spacing");
}

// The time steps of a header: dim[4] (time) when the file has a fourth dimension, else 1.
int stepsOf(const nifti_image& header) {
  return header.ndim >= 4 && header.dim[4] > 1 ? int(header.dim[4]) : 1;
}

// The header of a NIfTI file readNifti accepts, checked against the file before any voxel is
// read: a 3D volume (or, with `allowSteps`, a series of them along dim[4]), a datatype of known
// size, all its data there.
NiftiPtr checkedHeader(const std::string& path, bool allowSteps = false) {
  nifti_set_debug_level(0);  // we report errors ourselves, in one line
  NiftiPtr header(nifti_image_read(path.c_str(), 0));
  if (!header) throw FormatError(path, "not a readable NIfTI file");
  const glm::ivec3 dims(int(header->nx), int(header->ny), int(header->nz));
  for (int d = 5; d <= header->ndim && d <= 7; ++d)
    if (header->dim[d] > 1)
      throw FormatError(path, "has " + std::to_string(header->ndim) +
                                  " dimensions; voxwall reads 3D volumes and series of them "
                                  "(a fourth dimension, time)");
  if (!allowSteps && stepsOf(*header) > 1)
    throw FormatError(path, "holds " + std::to_string(stepsOf(*header)) +
                                " time steps: `voxwall compress` makes one .vwz of them");
  if (stepsOf(*header) > int(kMaxSteps))
    throw FormatError(path, "holds " + std::to_string(stepsOf(*header)) +
                                " time steps, more than a .vwz file holds (" +
                                std::to_string(kMaxSteps) + ")");
  checkDims(dims, path);
  if (header->nbyper <= 0 || header->nbyper > 8)
    throw FormatError(path, "unsupported NIfTI datatype " + std::to_string(header->datatype));
  // Check the data is all there before nifticlib reads it.
  const double need = double(header->iname_offset) + double(header->nvox) * header->nbyper;
  std::uint64_t have = 0;
  if (extensionOf(path).ends_with(".gz")) {
    have = gzipLength(path);
  } else {
    std::error_code ec;
    have = std::filesystem::file_size(path, ec);
    if (ec) throw FormatError(path, ec.message());
  }
  checkRawHeader(path, have);
  if (double(have) < need)
    throw FormatError(path, "truncated: " + std::to_string(have) +
                                " bytes of data, the header needs " +
                                std::to_string(std::uint64_t(need)));
  return header;
}

// The scaling nifticlib reports, as readNifti applies it (0 or a non-finite slope: none).
std::pair<double, double> scalingOf(const nifti_image& nim) {
  double slope = nim.scl_slope, inter = nim.scl_inter;
  if (slope == 0 || !std::isfinite(slope)) slope = 1.0, inter = 0.0;
  if (!std::isfinite(inter)) inter = 0.0;
  return {slope, inter};
}

glm::dvec3 spacingOf(const nifti_image& nim) {
  // Negative and non-finite spacings were refused by checkRawHeader; 0 (old ANALYZE files)
  // means unknown.
  glm::dvec3 spacing(nim.dx, nim.dy, nim.dz);
  for (int i = 0; i < 3; ++i)
    if (!(spacing[i] > 0)) spacing[i] = 1.0;
  return spacing;
}

struct Geometry {
  glm::dvec3 spacing;
  Orientation orientation;
};

// The spacing and orientation one of the header's index-to-RAS matrices gives, converted to LPS;
// nullopt when its columns are not finite and non-zero, or (unless `orthonormalize`) when they
// are not orthogonal.
std::optional<Geometry> geometryOf(const mat44& m, bool orthonormalize) {
  Geometry g;
  glm::dmat3 columns;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) columns[c][r] = double(m.m[r][c]) * (r < 2 ? -1.0 : 1.0);
  for (int r = 0; r < 3; ++r) g.orientation.origin[r] = double(m.m[r][3]) * (r < 2 ? -1.0 : 1.0);
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(g.orientation.origin[i])) return std::nullopt;
  for (int c = 0; c < 3; ++c) {
    const double length = glm::length(columns[c]);
    if (!(length > 0) || !std::isfinite(length)) return std::nullopt;
    g.spacing[c] = length;
    columns[c] /= length;
  }
  if (orientationProblem(columns).empty())
    g.orientation.direction = columns;
  else if (orthonormalize)
    g.orientation.direction = orthonormalized(columns);
  else
    return std::nullopt;
  return g;
}

// Where the voxels lie: the sform when its code is set and its axes are orthogonal, else the
// qform when its code is set, else a sheared sform's nearest rotation, else the identity (LPS,
// the file order, as voxwall rendered NIfTI before it read orientation) with pixdim's spacing.
Geometry geometryOf(const nifti_image& nim) {
  if (nim.sform_code > 0)
    if (auto g = geometryOf(nim.sto_xyz, false)) return *g;
  if (nim.qform_code > 0)
    if (auto g = geometryOf(nim.qto_xyz, false)) return *g;
  if (nim.sform_code > 0)
    if (auto g = geometryOf(nim.sto_xyz, true)) return *g;
  return {spacingOf(nim), Orientation{}};
}

}  // namespace

std::optional<SlabLayout> niftiSlabLayout(const std::string& path, int step) {
  const NiftiPtr header = checkedHeader(path, step >= 0);
  step = std::max(step, 0);
  if (step >= stepsOf(*header))
    throw std::invalid_argument(path + ": no step " + std::to_string(step));
  if (!header->iname || nifti_is_gzfile(header->iname)) return std::nullopt;
  const auto [slope, inter] = scalingOf(*header);
  if (slope != 1.0 || inter != 0.0) return std::nullopt;  // converted to float32 on reading
  SlabLayout slab;
  RawLayout& l = slab.layout;
  switch (header->datatype) {
    case DT_UINT8:
      l.type = ScalarType::UInt8;
      break;
    case DT_UINT16:
      l.type = ScalarType::UInt16;
      break;
    case DT_INT16:
      l.type = ScalarType::Int16;
      break;
    case DT_FLOAT32:
      l.type = ScalarType::Float32;
      break;
    default:
      return std::nullopt;  // converted on reading: read whole
  }
  slab.file = header->iname;
  l.dims = glm::ivec3(int(header->nx), int(header->ny), int(header->nz));
  const Geometry geometry = geometryOf(*header);
  l.spacing = geometry.spacing;
  l.orientation = geometry.orientation;
  l.headerBytes = std::uint64_t(std::max(0, header->iname_offset));
  l.bigEndian = scalarBytes(l.type) > 1 && header->byteorder != nifti_short_order();
  std::error_code ec;
  const std::uint64_t have = std::filesystem::file_size(slab.file, ec);
  if (ec) throw FormatError(path, slab.file + ": " + ec.message());
  const std::uint64_t need = l.headerBytes + std::uint64_t(header->nvox) * scalarBytes(l.type);
  if (have < need)
    throw FormatError(path, "truncated: " + std::to_string(have) +
                                " bytes of data, the header needs " + std::to_string(need));
  l.headerBytes += std::uint64_t(step) * std::uint64_t(l.dims.x) * std::uint64_t(l.dims.y) *
                   std::uint64_t(l.dims.z) * scalarBytes(l.type);
  return slab;
}

namespace {

// Step `step` of the file; `series`: the file may hold several.
Volume readStep(const std::string& path, int step, bool series) {
  NiftiPtr nim = checkedHeader(path, series);
  if (step < 0 || step >= stepsOf(*nim))
    throw std::invalid_argument(path + ": no step " + std::to_string(step));
  // One volume of the series: nifticlib reads the sub-brick (from a gzip stream too).
  void* stepData = nullptr;
  int select[8] = {-1, -1, -1, -1, step, -1, -1, -1};
  if (nifti_read_collapsed_image(nim.get(), select, &stepData) < 0 || !stepData)
    throw FormatError(path, "cannot read NIfTI voxel data (truncated or corrupt)");
  nim->data = stepData;  // freed with the image
  const Geometry geometry = geometryOf(*nim);
  const glm::dvec3 spacing = geometry.spacing;
  const glm::ivec3 dims(int(nim->nx), int(nim->ny), int(nim->nz));
  const auto [slope, inter] = scalingOf(*nim);
  const bool scaled = slope != 1.0 || inter != 0.0;

  Volume v;
  auto make = [&](ScalarType t) { v = Volume::allocate(dims, t, spacing); };
  switch (nim->datatype) {
    case DT_UINT8:
      make(scaled ? ScalarType::Float32 : ScalarType::UInt8);
      scaled ? convert<std::uint8_t, float>(nim->data, v, slope, inter)
             : convert<std::uint8_t, std::uint8_t>(nim->data, v, 1, 0);
      break;
    case DT_INT8:
      make(scaled ? ScalarType::Float32 : ScalarType::Int16);
      scaled ? convert<std::int8_t, float>(nim->data, v, slope, inter)
             : convert<std::int8_t, std::int16_t>(nim->data, v, 1, 0);
      break;
    case DT_UINT16:
      make(scaled ? ScalarType::Float32 : ScalarType::UInt16);
      scaled ? convert<std::uint16_t, float>(nim->data, v, slope, inter)
             : convert<std::uint16_t, std::uint16_t>(nim->data, v, 1, 0);
      break;
    case DT_INT16:
      make(scaled ? ScalarType::Float32 : ScalarType::Int16);
      scaled ? convert<std::int16_t, float>(nim->data, v, slope, inter)
             : convert<std::int16_t, std::int16_t>(nim->data, v, 1, 0);
      break;
    case DT_INT32:
      make(ScalarType::Float32);
      convert<std::int32_t, float>(nim->data, v, slope, inter);
      break;
    case DT_UINT32:
      make(ScalarType::Float32);
      convert<std::uint32_t, float>(nim->data, v, slope, inter);
      break;
    case DT_FLOAT32:
      make(ScalarType::Float32);
      convert<float, float>(nim->data, v, slope, inter);
      break;
    case DT_FLOAT64:
      make(ScalarType::Float32);
      convert<double, float>(nim->data, v, slope, inter);
      break;
    default:
      throw FormatError(
          path, std::string("unsupported NIfTI datatype ") + nifti_datatype_string(nim->datatype));
  }
  v.orientation = geometry.orientation;
  v.computeRange();
  return v;
}

}  // namespace

Volume readNifti(const std::string& path) { return readStep(path, 0, false); }

int niftiStepCount(const std::string& path) { return stepsOf(*checkedHeader(path, true)); }

Volume readNiftiStep(const std::string& path, int step) { return readStep(path, step, true); }

void writeNifti(const Volume& volume, const std::string& path) {
  writeNiftiSeries({volume}, path, 1.0);
}

void writeNiftiSeries(const std::vector<Volume>& steps, const std::string& path,
                      double stepSeconds) {
  if (steps.empty()) throw std::invalid_argument("writeNiftiSeries: no steps");
  const Volume& volume = steps.front();
  for (std::size_t k = 1; k < steps.size(); ++k)
    if (steps[k].dims != volume.dims || steps[k].type != volume.type)
      throw std::invalid_argument("writeNiftiSeries: step " + std::to_string(k) +
                                  " differs from step 0 in size or type");
  const int count = int(steps.size());
  int datatype = DT_UINT8;
  switch (volume.type) {
    case ScalarType::UInt8:
      datatype = DT_UINT8;
      break;
    case ScalarType::UInt16:
      datatype = DT_UINT16;
      break;
    case ScalarType::Int16:
      datatype = DT_INT16;
      break;
    case ScalarType::Float32:
      datatype = DT_FLOAT32;
      break;
  }
  int dims[8] = {count > 1 ? 4 : 3, volume.dims.x, volume.dims.y, volume.dims.z, count, 1, 1, 1};
  NiftiPtr nim(nifti_make_new_nim(dims, datatype, 1));
  if (!nim) throw FormatError(path, "cannot create NIfTI image");
  for (std::size_t k = 0; k < steps.size(); ++k)
    std::memcpy(static_cast<std::byte*>(nim->data) + k * volume.data.size(), steps[k].data.data(),
                volume.data.size());
  if (count > 1) {
    nim->dt = nim->pixdim[4] = float(stepSeconds);
    nim->time_units = NIFTI_UNITS_SEC;
  }
  nim->dx = nim->pixdim[1] = float(volume.spacing.x);
  nim->dy = nim->pixdim[2] = float(volume.spacing.y);
  nim->dz = nim->pixdim[3] = float(volume.spacing.z);
  // The orientation as both sform and qform (scanner anatomical), in NIfTI's RAS.
  mat44 m{};
  for (int r = 0; r < 3; ++r) {
    const double flip = r < 2 ? -1.0 : 1.0;
    for (int c = 0; c < 3; ++c)
      m.m[r][c] = float(flip * volume.orientation.direction[c][r] * volume.spacing[c]);
    m.m[r][3] = float(flip * volume.orientation.origin[r]);
  }
  m.m[3][3] = 1.0f;
  nim->sform_code = nim->qform_code = NIFTI_XFORM_SCANNER_ANAT;
  nim->sto_xyz = m;
  nim->sto_ijk = nifti_mat44_inverse(m);
  nifti_mat44_to_quatern(m, &nim->quatern_b, &nim->quatern_c, &nim->quatern_d, &nim->qoffset_x,
                         &nim->qoffset_y, &nim->qoffset_z, nullptr, nullptr, nullptr, &nim->qfac);
  nim->qto_xyz =
      nifti_quatern_to_mat44(nim->quatern_b, nim->quatern_c, nim->quatern_d, nim->qoffset_x,
                             nim->qoffset_y, nim->qoffset_z, nim->dx, nim->dy, nim->dz, nim->qfac);
  nim->qto_ijk = nifti_mat44_inverse(nim->qto_xyz);
  nim->nifti_type = NIFTI_FTYPE_NIFTI1_1;
  // The temporary keeps the extension so nifticlib picks the same (gzip or not) encoding.
  const bool gz = extensionOf(path).ends_with(".gz");
  const std::string tmp = temporaryNameFor(path) + (gz ? ".nii.gz" : ".nii");
  std::filesystem::remove(tmp);
  if (nifti_set_filenames(nim.get(), tmp.c_str(), 0, 1) != 0)
    throw FormatError(path, "cannot set NIfTI file name");
  nifti_set_debug_level(0);      // the error is reported below, in one line
  nifti_image_write(nim.get());  // returns void: check the result on disk
  // A full disk leaves a short file (or a cut gzip stream): it must hold the header and every
  // voxel before it is renamed into place.
  const std::uint64_t want =
      std::uint64_t(sizeof(nifti_1_header)) + 4 + volume.data.size() * steps.size();
  std::uint64_t written = 0;
  try {
    std::error_code ec;
    written = gz ? gzipLength(tmp) : std::uint64_t(std::filesystem::file_size(tmp, ec));
    if (ec) written = 0;
    if (written < want)
      throw FormatError(path, "cannot write: " + std::to_string(written) + " of " +
                                  std::to_string(want) + " bytes reached the disk (full?)");
    syncFile(tmp, path);
  } catch (const FormatError& e) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    if (e.file() == path) throw;
    throw FormatError(path, "cannot write: the file written is cut short (disk full?)");
  }
  commitTemporary(tmp, path);
}

}  // namespace voxwall::codec
