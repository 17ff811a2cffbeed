// NRRD through teem: attached (.nrrd) or detached (.nhdr) headers, every encoding teem reads.
#include <bzlib.h>
#include <teem/nrrd.h>
#include <unistd.h>
#include <zlib.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <glm/geometric.hpp>
#include <memory>
#include <sstream>
#include <string_view>
#include <vector>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>

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
  // teem quotes what it could not parse: from a garbage file that is anything, terminal escapes
  // included. Keep it printable and short.
  std::string clean;
  for (const unsigned char c : last) {
    if (clean.size() >= 160) {
      clean += "...";
      break;
    }
    clean += c >= 0x20 && c < 0x7f ? char(c) : '?';
  }
  return clean;
}

// Where an attached header ends: after the first empty line. 0 when there is none.
std::uint64_t attachedDataOffset(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return 0;
  std::vector<char> head(1 << 20);
  const std::size_t n = std::fread(head.data(), 1, head.size(), f);
  std::fclose(f);
  const std::string_view text(head.data(), n);
  for (const std::string_view end : {"\n\n", "\n\r\n"})
    if (const auto at = text.find(end); at != std::string_view::npos) return at + end.size();
  return 0;
}

// Decompresses a gzip or bzip2 stream from `offset` of `file` without keeping the output and
// returns how many bytes it produced, stopping at `limit`: a compressed file is judged by what
// it really holds, not by a ratio (bzip2 reaches far beyond 1000:1).
std::uint64_t decodedBytes(const std::string& file, std::uint64_t offset, bool bzip2,
                           std::uint64_t limit) {
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (!f) return 0;
  std::vector<char> buffer(1 << 20);
  std::uint64_t total = 0;
  if (std::fseek(f, long(offset), SEEK_SET) != 0) {
    std::fclose(f);
    return 0;
  }
  if (bzip2) {
    int err = BZ_OK;
    BZFILE* bz = BZ2_bzReadOpen(&err, f, 0, 0, nullptr, 0);
    while (err == BZ_OK && total < limit) {
      const int got = BZ2_bzRead(&err, bz, buffer.data(), int(buffer.size()));
      if (got > 0) total += std::uint64_t(got);
    }
    BZ2_bzReadClose(&err, bz);
    std::fclose(f);
    return total;
  }
  gzFile gz = gzdopen(::dup(::fileno(f)), "rb");
  std::fclose(f);
  if (!gz) return 0;
  // gzdopen reads from the descriptor's position, which fseek set.
  while (total < limit) {
    const int got = gzread(gz, buffer.data(), unsigned(buffer.size()));
    if (got <= 0) break;
    total += std::uint64_t(got);
  }
  gzclose_r(gz);
  return total;
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
  std::vector<std::pair<std::string, std::uint64_t>> files;  // data file, where its data starts
  if (io->dataFNArr && io->dataFNArr->len > 0) {
    for (unsigned i = 0; i < io->dataFNArr->len; ++i) {
      fs::path data = io->dataFN[i];
      if (data.is_relative()) data = fs::path(path).parent_path() / data;
      if (!fs::is_regular_file(data, ec)) return;  // teem reports it in its own words
      files.emplace_back(data.string(), 0);
    }
  } else {
    files.emplace_back(path, attachedDataOffset(path));
  }
  const bool compressed = io->encoding && io->encoding->isCompression;
  const bool bzip2 = compressed && io->encoding == nrrdEncodingBzip2;
  double have = 0;
  for (const auto& [file, offset] : files) {
    if (compressed) {
      have += double(decodedBytes(file, offset, bzip2, std::uint64_t(need - have) + 1));
    } else {
      const auto bytes = fs::file_size(file, ec);
      if (ec) return;
      have += double(bytes);
    }
  }
  if (need > have)
    throw FormatError(path, "truncated: the header needs " + std::to_string(std::uint64_t(need)) +
                                " bytes of data, the file holds " +
                                std::to_string(std::uint64_t(have)) +
                                (compressed ? " (decompressed)" : ""));
}

// The voxel spacing of axes first .. first+2 (1 where the header gives none).
glm::dvec3 spacingOf(Nrrd* nin, unsigned first) {
  glm::dvec3 spacing(1.0);
  for (int i = 0; i < 3; ++i) {
    double s = 0, dir[NRRD_SPACE_DIM_MAX] = {};
    const int status = nrrdSpacingCalculate(nin, first + unsigned(i), &s, dir);
    if ((status == nrrdSpacingStatusScalarNoSpace || status == nrrdSpacingStatusScalarWithSpace ||
         status == nrrdSpacingStatusDirection) &&
        std::isfinite(s) && s > 0)
      spacing[i] = s;
  }
  return spacing;
}

// Where the voxels of axes first .. first+2 lie: from `space directions` and `space origin` when
// every axis has a direction, converted from the header's `space` to LPS (scanner-xyz is LPS;
// spaces without anatomical names are taken as LPS); directions that are not orthogonal become
// their nearest rotation. The identity otherwise.
Orientation orientationOf(Nrrd* nin, unsigned first) {
  Orientation o;
  if (nin->spaceDim < 3) return o;
  glm::dvec3 flip(1.0);
  switch (nin->space) {
    case nrrdSpaceRightAnteriorSuperior:
    case nrrdSpaceRightAnteriorSuperiorTime:
      flip = {-1, -1, 1};
      break;
    case nrrdSpaceLeftAnteriorSuperior:
    case nrrdSpaceLeftAnteriorSuperiorTime:
      flip = {1, -1, 1};
      break;
    default:
      break;
  }
  glm::dmat3 columns;
  for (int i = 0; i < 3; ++i) {
    double s = 0, dir[NRRD_SPACE_DIM_MAX] = {};
    if (nrrdSpacingCalculate(nin, first + unsigned(i), &s, dir) != nrrdSpacingStatusDirection)
      return o;
    for (int r = 0; r < 3; ++r) columns[i][r] = dir[r] * flip[r];
    const double length = glm::length(columns[i]);
    if (!(length > 0) || !std::isfinite(length)) return o;
    columns[i] /= length;
  }
  o.direction = orientationProblem(columns).empty() ? columns : orthonormalized(columns);
  for (int r = 0; r < 3; ++r)
    if (std::isfinite(nin->spaceOrigin[r])) o.origin[r] = nin->spaceOrigin[r] * flip[r];
  return o;
}

// The time steps of a 4D NRRD: the size of its last (slowest) axis when the first is not a
// single-sample axis and the last is not a space or domain axis (its kind is time, list or
// unsaid); 1 for a 3D volume. Throws for more steps than a .vwz holds.
int timeStepsOf(const Nrrd& n, const std::string& path) {
  if (n.dim != 4 || n.axis[0].size == 1) return 1;
  const int kind = n.axis[3].kind;
  if (kind != nrrdKindTime && kind != nrrdKindList && kind != nrrdKindUnknown) return 1;
  if (n.axis[3].size > kMaxSteps)
    throw FormatError(path, "holds " + std::to_string(n.axis[3].size) +
                                " time steps, more than a .vwz file holds (" +
                                std::to_string(kMaxSteps) + ")");
  return int(n.axis[3].size);
}

// timeStepsOf, when `step` is one of them (or -1 for a file of one volume); else throws.
int stepsAllowing(const Nrrd& n, int step, const std::string& path) {
  const int steps = timeStepsOf(n, path);
  if (step < 0 && steps > 1)
    throw FormatError(path, "holds " + std::to_string(steps) +
                                " time steps: `voxwall compress` makes one .vwz of them");
  if (step >= steps)
    throw std::invalid_argument(path + ": no step " + std::to_string(step) + " (it holds " +
                                std::to_string(steps) + ")");
  return steps;
}

// The volume of `nin` starting at element `offset` (a time step's first), in voxwall's type for
// its NRRD type; its geometry from the axes from `first` on.
Volume volumeOf(Nrrd* nin, unsigned first, std::size_t offset, const std::string& path);

}  // namespace

std::optional<SlabLayout> nrrdSlabLayout(const std::string& path, int step) {
  checkNrrdHeader(path);
  std::unique_ptr<Nrrd, NrrdNuker> header(nrrdNew());
  std::unique_ptr<NrrdIoState, IoStateDeleter> io(nrrdIoStateNew());
  io->skipData = AIR_TRUE;
  if (nrrdLoad(header.get(), path.c_str(), io.get())) throw FormatError(path, teemError());
  const int steps = stepsAllowing(*header, step, path);
  const unsigned first = header->dim == 4 && header->axis[0].size == 1 ? 1 : 0;
  if (header->dim - first != (steps > 1 ? 4u : 3u) || io->encoding != nrrdEncodingRaw ||
      io->lineSkip != 0 || io->byteSkip < -1 || (io->dataFNArr && io->dataFNArr->len > 1))
    return std::nullopt;
  SlabLayout slab;
  RawLayout& l = slab.layout;
  switch (header->type) {
    case nrrdTypeUChar:
      l.type = ScalarType::UInt8;
      break;
    case nrrdTypeUShort:
      l.type = ScalarType::UInt16;
      break;
    case nrrdTypeShort:
      l.type = ScalarType::Int16;
      break;
    case nrrdTypeFloat:
      l.type = ScalarType::Float32;
      break;
    default:
      return std::nullopt;  // converted on reading: read whole
  }
  l.dims = glm::ivec3(int(header->axis[first].size), int(header->axis[first + 1].size),
                      int(header->axis[first + 2].size));
  checkDims(l.dims, path);
  l.spacing = spacingOf(header.get(), first);
  l.orientation = orientationOf(header.get(), first);
  l.bigEndian = scalarBytes(l.type) > 1 && io->endian == airEndianBig;
  namespace fs = std::filesystem;
  std::uint64_t start = 0;
  if (io->dataFNArr && io->dataFNArr->len == 1) {
    fs::path data = io->dataFN[0];
    if (data.is_relative()) data = fs::path(path).parent_path() / data;
    slab.file = data.string();
  } else {
    slab.file = path;
    start = attachedDataOffset(path);
    if (start == 0) return std::nullopt;
  }
  std::error_code ec;
  const std::uint64_t have = fs::file_size(slab.file, ec);
  if (ec) throw FormatError(path, slab.file + ": " + ec.message());
  const std::uint64_t stepBytes = std::uint64_t(l.dims.x) * std::uint64_t(l.dims.y) *
                                  std::uint64_t(l.dims.z) * scalarBytes(l.type);
  const std::uint64_t need = stepBytes * std::uint64_t(steps);
  // "byte skip: -1" means the voxels are the file's last bytes.
  l.headerBytes =
      io->byteSkip == -1 ? have - std::min(have, need) : start + std::uint64_t(io->byteSkip);
  if (have < l.headerBytes + need)
    throw FormatError(path, "truncated: the header needs " + std::to_string(need) +
                                " bytes of data, the file holds " +
                                std::to_string(have - std::min(have, l.headerBytes)));
  if (step > 0) l.headerBytes += std::uint64_t(step) * stepBytes;
  return slab;
}

namespace {

// Step `step` of a NRRD file (-1: the file must hold one volume).
Volume readNrrdVolume(const std::string& path, int step) {
  checkNrrdHeader(path);
  std::unique_ptr<Nrrd, NrrdNuker> nin(nrrdNew());
  if (nrrdLoad(nin.get(), path.c_str(), nullptr)) throw FormatError(path, teemError());
  const int steps = stepsAllowing(*nin, step, path);
  unsigned first = 0;
  // Allow a leading axis of size 1 (e.g. a single-component "vector" axis).
  if (nin->dim == 4 && nin->axis[0].size == 1) first = 1;
  if (nin->dim - first != (steps > 1 ? 4u : 3u))
    throw FormatError(path, "has " + std::to_string(nin->dim) +
                                " axes; a 3D volume or a series of them (a fourth axis, time) is "
                                "needed");
  const std::size_t voxels = std::size_t(nin->axis[first].size) *
                             std::size_t(nin->axis[first + 1].size) *
                             std::size_t(nin->axis[first + 2].size);
  return volumeOf(nin.get(), first, std::size_t(std::max(step, 0)) * voxels, path);
}

Volume volumeOf(Nrrd* nin, unsigned first, std::size_t offset, const std::string& path) {
  const glm::ivec3 dims(int(nin->axis[first].size), int(nin->axis[first + 1].size),
                        int(nin->axis[first + 2].size));
  checkDims(dims, path);
  const glm::dvec3 spacing = spacingOf(nin, first);
  const void* data =
      static_cast<const char*>(nin->data) + offset * std::size_t(nrrdElementSize(nin));
  Volume v;
  auto make = [&](ScalarType t) { v = Volume::allocate(dims, t, spacing); };
  switch (nin->type) {
    case nrrdTypeUChar:
      make(ScalarType::UInt8);
      convert<unsigned char, std::uint8_t>(data, v);
      break;
    case nrrdTypeChar:
      make(ScalarType::Int16);
      convert<signed char, std::int16_t>(data, v);
      break;
    case nrrdTypeUShort:
      make(ScalarType::UInt16);
      convert<unsigned short, std::uint16_t>(data, v);
      break;
    case nrrdTypeShort:
      make(ScalarType::Int16);
      convert<short, std::int16_t>(data, v);
      break;
    case nrrdTypeInt:
      make(ScalarType::Float32);
      convert<int, float>(data, v);
      break;
    case nrrdTypeUInt:
      make(ScalarType::Float32);
      convert<unsigned, float>(data, v);
      break;
    case nrrdTypeFloat:
      make(ScalarType::Float32);
      convert<float, float>(data, v);
      break;
    case nrrdTypeDouble:
      make(ScalarType::Float32);
      convert<double, float>(data, v);
      break;
    default:
      throw FormatError(path, "unsupported NRRD type " + std::to_string(nin->type));
  }
  v.orientation = orientationOf(nin, first);
  v.computeRange();
  return v;
}

}  // namespace

Volume readNrrd(const std::string& path) { return readNrrdVolume(path, -1); }

int nrrdStepCount(const std::string& path) {
  checkNrrdHeader(path);
  std::unique_ptr<Nrrd, NrrdNuker> header(nrrdNew());
  std::unique_ptr<NrrdIoState, IoStateDeleter> io(nrrdIoStateNew());
  io->skipData = AIR_TRUE;
  if (nrrdLoad(header.get(), path.c_str(), io.get())) throw FormatError(path, teemError());
  return timeStepsOf(*header, path);
}

Volume readNrrdStep(const std::string& path, int step) { return readNrrdVolume(path, step); }

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
  // The orientation as an LPS space with a direction (spacing included) and an origin.
  double directions[3][NRRD_SPACE_DIM_MAX] = {};
  double origin[NRRD_SPACE_DIM_MAX] = {};
  for (int a = 0; a < 3; ++a) {
    for (int r = 0; r < 3; ++r)
      directions[a][r] = volume.orientation.direction[a][r] * volume.spacing[a];
    origin[a] = volume.orientation.origin[a];
  }
  if (nrrdSpaceSet(nout.get(), nrrdSpaceLeftPosteriorSuperior) ||
      nrrdSpaceOriginSet(nout.get(), origin))
    throw FormatError(path, teemError());
  nrrdAxisInfoSet_nva(nout.get(), nrrdAxisInfoSpaceDirection, directions);
  std::unique_ptr<NrrdIoState, IoStateDeleter> io(nrrdIoStateNew());
  if (nrrdEncodingGzip->available()) io->encoding = nrrdEncodingGzip;
  // A detached header names its data file, so it is written in place; an attached .nrrd goes
  // through a temporary (keeping its extension, which teem reads) and a rename.
  const bool detached = extensionOf(path) == "nhdr";
  const std::string target = detached ? path : temporaryNameFor(path) + ".nrrd";
  if (nrrdSave(target.c_str(), nout.get(), io.get())) {
    std::error_code ec;
    if (!detached) std::filesystem::remove(target, ec);
    throw FormatError(path, "cannot write: " + teemError());
  }
  // teem does not notice every failed write (a full disk cuts the gzip stream): read back what
  // reached the disk before the file gets its name.
  try {
    checkNrrdHeader(target);
    syncFile(target, path);
  } catch (const FormatError&) {
    std::error_code ec;
    if (!detached) std::filesystem::remove(target, ec);
    throw FormatError(path, "cannot write: the file written is cut short (disk full?)");
  }
  if (!detached) commitTemporary(target, path);
}

}  // namespace voxwall::codec
