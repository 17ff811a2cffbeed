// NRRD through teem: attached (.nrrd) or detached (.nhdr) headers, every encoding teem reads.
#include <teem/nrrd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <sstream>
#include <voxwall/codec/errors.hpp>
#include <voxwall/codec/volume_io.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {
namespace {

struct NrrdNuker {
  void operator()(Nrrd* n) const { nrrdNuke(n); }
};
struct NrrdNixer {
  void operator()(Nrrd* n) const { nrrdNix(n); }
};
struct IoStateDeleter {
  void operator()(NrrdIoState* s) const { nrrdIoStateNix(s); }
};

// teem's biff messages are several lines, outermost first: keep the innermost, on one line.
std::string teemError() {
  char* raw = biffGetDone(NRRD);
  std::string all = raw ? raw : "unknown teem error";
  std::free(raw);
  std::istringstream lines(all);
  std::string line, last;
  while (std::getline(lines, line))
    if (line.find_first_not_of(" \t") != std::string::npos) last = line;
  const auto colon = last.find(": ");
  if (last.rfind("[nrrd]", 0) == 0 && colon != std::string::npos) last = last.substr(colon + 2);
  while (!last.empty() && (last.back() == '\n' || last.back() == ' ')) last.pop_back();
  return last;
}

template <class Src, class Dst>
void convert(const void* src, Volume& v) {
  const Src* s = static_cast<const Src*>(src);
  auto d = v.as<Dst>();
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = Dst(s[i]);
}

// Reads only the header and refuses a file whose header asks for more than the file can hold
// (or more than kMaxVoxels), before teem allocates anything for the data.
void checkNrrdHeader(const std::string& path) {
  std::unique_ptr<Nrrd, NrrdNuker> header(nrrdNew());
  std::unique_ptr<NrrdIoState, IoStateDeleter> io(nrrdIoStateNew());
  io->skipData = AIR_TRUE;
  if (nrrdLoad(header.get(), path.c_str(), io.get())) throw FormatError(path, teemError());
  double elements = 1;
  for (unsigned a = 0; a < header->dim; ++a) elements *= double(header->axis[a].size);
  if (elements > double(kMaxVoxels))
    throw FormatError(path, "header asks for " + std::to_string(elements) +
                                " values, over the limit of " + std::to_string(kMaxVoxels));
  const double need = elements * double(nrrdElementSize(header.get()));
  // What is on disk: the detached data files (relative to the header), or this file.
  namespace fs = std::filesystem;
  std::error_code ec;
  double onDisk = 0;
  if (io->dataFNArr && io->dataFNArr->len > 0) {
    for (unsigned i = 0; i < io->dataFNArr->len; ++i) {
      fs::path data = io->dataFN[i];
      if (data.is_relative()) data = fs::path(path).parent_path() / data;
      const auto bytes = fs::file_size(data, ec);
      if (ec) return;  // teem reports a missing data file in its own words
      onDisk += double(bytes);
    }
  } else {
    onDisk = double(fs::file_size(path, ec));
    if (ec) return;
  }
  // gzip and bzip2 expand at most about 1000:1.
  const double bound = io->encoding && io->encoding->isCompression ? 1100.0 * onDisk : onDisk;
  if (need > bound)
    throw FormatError(path, "truncated: the header needs " + std::to_string(std::uint64_t(need)) +
                                " bytes of data, the file holds " +
                                std::to_string(std::uint64_t(onDisk)));
}

}  // namespace

Volume readNrrd(const std::string& path) {
  checkNrrdHeader(path);
  std::unique_ptr<Nrrd, NrrdNuker> nin(nrrdNew());
  if (nrrdLoad(nin.get(), path.c_str(), nullptr)) throw FormatError(path, teemError());
  unsigned first = 0;
  // Allow a leading axis of size 1 (e.g. a single-component "vector" axis).
  if (nin->dim == 4 && nin->axis[0].size == 1) first = 1;
  if (nin->dim - first != 3)
    throw FormatError(path, "has " + std::to_string(nin->dim) + " axes; a 3D volume is needed");
  const glm::ivec3 dims(int(nin->axis[first].size), int(nin->axis[first + 1].size),
                        int(nin->axis[first + 2].size));
  checkDims(dims, path);
  glm::dvec3 spacing(1.0);
  for (int i = 0; i < 3; ++i) {
    double s = 0, dir[NRRD_SPACE_DIM_MAX] = {};
    const int status = nrrdSpacingCalculate(nin.get(), first + unsigned(i), &s, dir);
    if ((status == nrrdSpacingStatusScalarNoSpace || status == nrrdSpacingStatusScalarWithSpace ||
         status == nrrdSpacingStatusDirection) &&
        std::isfinite(s) && s > 0)
      spacing[i] = s;
  }
  Volume v;
  auto make = [&](ScalarType t) { v = Volume::allocate(dims, t, spacing); };
  switch (nin->type) {
    case nrrdTypeUChar:
      make(ScalarType::UInt8);
      convert<unsigned char, std::uint8_t>(nin->data, v);
      break;
    case nrrdTypeChar:
      make(ScalarType::Int16);
      convert<signed char, std::int16_t>(nin->data, v);
      break;
    case nrrdTypeUShort:
      make(ScalarType::UInt16);
      convert<unsigned short, std::uint16_t>(nin->data, v);
      break;
    case nrrdTypeShort:
      make(ScalarType::Int16);
      convert<short, std::int16_t>(nin->data, v);
      break;
    case nrrdTypeInt:
      make(ScalarType::Float32);
      convert<int, float>(nin->data, v);
      break;
    case nrrdTypeUInt:
      make(ScalarType::Float32);
      convert<unsigned, float>(nin->data, v);
      break;
    case nrrdTypeFloat:
      make(ScalarType::Float32);
      convert<float, float>(nin->data, v);
      break;
    case nrrdTypeDouble:
      make(ScalarType::Float32);
      convert<double, float>(nin->data, v);
      break;
    default:
      throw FormatError(path, "unsupported NRRD type " + std::to_string(nin->type));
  }
  v.computeRange();
  return v;
}

void writeNrrd(const Volume& volume, const std::string& path) {
  int type = nrrdTypeUChar;
  switch (volume.type) {
    case ScalarType::UInt8:
      type = nrrdTypeUChar;
      break;
    case ScalarType::UInt16:
      type = nrrdTypeUShort;
      break;
    case ScalarType::Int16:
      type = nrrdTypeShort;
      break;
    case ScalarType::Float32:
      type = nrrdTypeFloat;
      break;
  }
  std::unique_ptr<Nrrd, NrrdNixer> nout(nrrdNew());
  std::size_t sizes[3] = {std::size_t(volume.dims.x), std::size_t(volume.dims.y),
                          std::size_t(volume.dims.z)};
  if (nrrdWrap_nva(nout.get(), const_cast<std::byte*>(volume.data.data()), type, 3, sizes))
    throw FormatError(path, teemError());
  double spacings[3] = {volume.spacing.x, volume.spacing.y, volume.spacing.z};
  nrrdAxisInfoSet_nva(nout.get(), nrrdAxisInfoSpacing, spacings);
  std::unique_ptr<NrrdIoState, IoStateDeleter> io(nrrdIoStateNew());
  if (nrrdEncodingGzip->available()) io->encoding = nrrdEncodingGzip;
  // A detached header names its data file, so it is written in place; an attached .nrrd goes
  // through a temporary (keeping its extension, which teem reads) and a rename.
  const bool detached = extensionOf(path) == "nhdr";
  const std::string target = detached ? path : temporaryNameFor(path) + ".nrrd";
  if (nrrdSave(target.c_str(), nout.get(), io.get())) {
    std::error_code ec;
    if (!detached) std::filesystem::remove(target, ec);
    throw FormatError(path, teemError());
  }
  if (!detached) commitTemporary(target, path);
}

}  // namespace voxwall::codec
