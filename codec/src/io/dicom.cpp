// DICOM series through GDCM: the files of a folder grouped by series, one series' slices sorted
// along their normal and checked for the gaps, sizes and orientations a volume needs, their
// pixels decoded by GDCM (any transfer syntax it decodes) and rescaled to their real values.
#include <gdcmImageReader.h>
#include <gdcmScanner.h>
#include <gdcmSequenceOfFragments.h>
#include <gdcmTrace.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>

#include "../file_util.hpp"
#include "dicom_checks.hpp"
#include "dicom_frames.hpp"
#include "dicom_slices.hpp"

namespace voxwall::codec {
namespace {

namespace fs = std::filesystem;
using dicom::checkCompressedStart;
using dicom::checkElements;
using dicom::checkImageHeader;
using dicom::fittedGap;
using dicom::fixed;
using dicom::numbersOf;
using dicom::placeSlices;
using dicom::SliceAxes;
using dicom::SliceHeader;
using dicom::trimmed;
using dicom::undoGantryTilt;

// At most this many files are looked at under one folder: a folder that holds more is refused
// rather than read for minutes.
constexpr std::size_t kMaxFiles = 200000;

const gdcm::Tag kSeriesUid(0x0020, 0x000e), kSeriesDescription(0x0008, 0x103e),
    kModality(0x0008, 0x0060), kRows(0x0028, 0x0010), kColumns(0x0028, 0x0011),
    kPosition(0x0020, 0x0032), kOrientation(0x0020, 0x0037), kFrames(0x0028, 0x0008),
    kSamples(0x0028, 0x0002), kBitsAllocated(0x0028, 0x0100), kPixelData(0x7fe0, 0x0010);

// GDCM reports problems on stderr through its trace; the reader reports them itself, in one line.
void quietGdcm() {
  static std::once_flag once;
  std::call_once(once, [] {
    gdcm::Trace::SetDebug(false);
    gdcm::Trace::SetWarning(false);
    gdcm::Trace::SetError(false);
  });
}

int intOf(const std::string& text, int fallback) {
  const auto v = numbersOf(text);
  return v.size() == 1 && v[0] == std::floor(v[0]) && std::abs(v[0]) < 1e9 ? int(v[0]) : fallback;
}

bool startsAsDicom(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  char head[132];
  return in.read(head, sizeof head) && std::memcmp(head + 128, "DICM", 4) == 0;
}

bool isDicomDirName(const fs::path& p) {
  std::string name = p.filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return char(std::toupper(c)); });
  return name == "DICOMDIR";
}

// The DICOM files under a folder (with its sub-folders), or the one file named; a DICOMDIR stands
// for the folder it lies in. Files that do not start as DICOM Part 10 files do are left out.
std::vector<std::string> dicomFilesOf(const std::string& path) {
  fs::path root(path);
  std::error_code ec;
  if (fs::is_regular_file(root, ec) && !isDicomDirName(root)) {
    if (!startsAsDicom(root))
      throw FormatError(path, "not a DICOM Part 10 file (no 'DICM' after a 128-byte preamble)");
    return {path};
  }
  if (isDicomDirName(root)) root = root.parent_path().empty() ? fs::path(".") : root.parent_path();
  std::vector<std::string> files;
  std::size_t seen = 0;
  for (fs::recursive_directory_iterator it(root, fs::directory_options::skip_permission_denied, ec),
       end;
       !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file(ec) || isDicomDirName(it->path())) continue;
    if (++seen > kMaxFiles)
      throw FormatError(path, "holds more than " + std::to_string(kMaxFiles) +
                                  " files; point at the folder of one series");
    if (startsAsDicom(it->path())) files.push_back(it->path().string());
  }
  if (ec) throw FormatError(path, "cannot list its files: " + ec.message());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw FormatError(path, "holds no DICOM files (none starts with 'DICM')");
  return files;
}

struct Series {
  DicomSeriesInfo info;
  std::vector<SliceHeader> slices;
};

// The image files under `path` grouped by series (files without Rows/Columns, such as reports
// and presentation states, are not images and are left out).
std::map<std::string, Series> scanSeries(const std::string& path) {
  quietGdcm();
  const std::vector<std::string> files = dicomFilesOf(path);
  std::map<std::string, std::string> syntaxOf;  // each file's transfer syntax UID
  for (const std::string& f : files)            // before the scanner
    syntaxOf[f] = checkElements(f).transferSyntax;
  gdcm::Scanner scanner;
  for (const gdcm::Tag& t : {kSeriesUid, kSeriesDescription, kModality, kRows, kColumns, kPosition,
                             kOrientation, kFrames, kSamples, kBitsAllocated})
    scanner.AddTag(t);
  if (!scanner.Scan(files)) throw FormatError(path, "GDCM could not scan its DICOM files");
  std::map<std::string, Series> out;
  for (const std::string& f : files) {
    if (!scanner.IsKey(f.c_str()))
      throw FormatError(f, "not a readable DICOM file (truncated or corrupt header)");
    auto value = [&](const gdcm::Tag& t) { return trimmed(scanner.GetValue(f.c_str(), t)); };
    SliceHeader h;
    h.file = f;
    h.rows = intOf(value(kRows), 0);
    h.columns = intOf(value(kColumns), 0);
    if (h.rows <= 0 || h.columns <= 0) continue;
    h.series = value(kSeriesUid);
    h.frames = intOf(value(kFrames), 1);
    h.samples = intOf(value(kSamples), 1);
    // GDCM's decoders assert on an image of no bytes (found by the DICOM fuzz target).
    const int bits = intOf(value(kBitsAllocated), 0);
    const bool compressed =
        gdcm::TransferSyntax(gdcm::TransferSyntax::GetTSType(syntaxOf[f].c_str())).IsEncapsulated();
    // Nor can they decode compressed 32-bit pixels (the JPEG codec dereferenced a null decoder).
    if (bits != 8 && bits != 16 && (bits != 32 || compressed))
      throw FormatError(f, "has Bits Allocated " + value(kBitsAllocated) +
                               "; voxwall reads images of 8, 16 or (uncompressed) 32 bits");
    if (h.frames < 1) throw FormatError(f, "has Number of Frames " + value(kFrames));
    h.position = numbersOf(value(kPosition));
    h.decimals = dicom::decimalsOf(value(kPosition));
    h.orientation = numbersOf(value(kOrientation));
    Series& s = out[h.series];
    if (s.slices.empty()) {
      s.info.uid = h.series;
      s.info.description = value(kSeriesDescription);
      s.info.modality = value(kModality);
      s.info.columns = h.columns, s.info.rows = h.rows;
    }
    ++s.info.files;
    s.slices.push_back(std::move(h));
  }
  if (out.empty()) throw FormatError(path, "holds DICOM files but no images");
  return out;
}

std::string describe(const DicomSeriesInfo& s) {
  std::string d = (s.uid.empty() ? std::string("(no Series Instance UID)") : s.uid);
  if (!s.description.empty()) d += " \"" + s.description + "\"";
  d += " (" + (s.modality.empty() ? std::string("?") : s.modality) + ", " +
       std::to_string(s.files) + (s.files == 1 ? " file, " : " files, ") +
       std::to_string(s.columns) + "x" + std::to_string(s.rows) + ")";
  return d;
}

const Series& pickSeries(const std::map<std::string, Series>& all, const std::string& path,
                         const DicomOptions& options) {
  if (!options.series.empty()) {
    const auto it = all.find(options.series);
    if (it != all.end()) return it->second;
    std::string list;
    for (auto& [uid, s] : all) list += (list.empty() ? "" : "; ") + describe(s.info);
    throw FormatError(path, "holds no series " + options.series + " (it holds " + list + ")");
  }
  if (all.size() == 1) return all.begin()->second;
  std::string list;
  for (auto& [uid, s] : all) list += (list.empty() ? "" : "; ") + describe(s.info);
  throw FormatError(path, "holds " + std::to_string(all.size()) +
                              " series; choose one with --series UID: " + list);
}

// The volume's stored values before rescaling, one type for the whole series.
enum class Stored { U8, I8, U16, I16, U32, I32 };

Stored storedOf(const gdcm::PixelFormat& pf, const std::string& file) {
  if (pf.GetSamplesPerPixel() != 1)
    throw FormatError(file, "is a colour image (" + std::to_string(pf.GetSamplesPerPixel()) +
                                " samples per pixel); voxwall reads greyscale DICOM");
  switch (pf.GetScalarType()) {
    case gdcm::PixelFormat::UINT8:
      return Stored::U8;
    case gdcm::PixelFormat::INT8:
      return Stored::I8;
    case gdcm::PixelFormat::UINT16:
      return Stored::U16;
    case gdcm::PixelFormat::INT16:
      return Stored::I16;
    case gdcm::PixelFormat::UINT32:
      return Stored::U32;
    case gdcm::PixelFormat::INT32:
      return Stored::I32;
    default:
      throw FormatError(file, std::string("pixel format ") + pf.GetScalarTypeAsString() +
                                  " is not read (8, 16 or 32-bit integers are)");
  }
}

std::size_t storedBytes(Stored s) {
  switch (s) {
    case Stored::U8:
    case Stored::I8:
      return 1;
    case Stored::U16:
    case Stored::I16:
      return 2;
    default:
      return 4;
  }
}

template <class F>
decltype(auto) dispatchStored(Stored s, F&& f) {
  switch (s) {
    case Stored::U8:
      return f(std::uint8_t{});
    case Stored::I8:
      return f(std::int8_t{});
    case Stored::U16:
      return f(std::uint16_t{});
    case Stored::I16:
      return f(std::int16_t{});
    case Stored::U32:
      return f(std::uint32_t{});
    case Stored::I32:
      return f(std::int32_t{});
  }
  throw std::logic_error("unknown stored type");
}

// One decoded image (a slice, or every frame of a multi-frame file) written to `out`.
struct Decoded {
  Stored stored;
  double slope = 1, intercept = 0;
  glm::dvec3 spacing{1, 1, 1};
  unsigned dims[3] = {1, 1, 1};
  double cosines[6] = {1, 0, 0, 0, 1, 0};  // GDCM's direction cosines (row, then column)
  double origin[3] = {0, 0, 0};            // and origin (the first frame's position)
};

// The orientation of an image from its row and column direction cosines and its position: the
// identity when the cosines are not two perpendicular unit vectors.
Orientation orientationOf(const double* cosines, const double* position) {
  Orientation o;
  const glm::dvec3 row(cosines[0], cosines[1], cosines[2]),
      column(cosines[3], cosines[4], cosines[5]);
  const glm::dmat3 m(row, column, glm::cross(row, column));
  const glm::dvec3 origin(position[0], position[1], position[2]);
  if (!orientationProblem(m).empty() || !std::isfinite(origin.x) || !std::isfinite(origin.y) ||
      !std::isfinite(origin.z))
    return o;
  o.direction = m;
  o.origin = origin;
  return o;
}

Decoded decode(const std::string& file, std::vector<std::byte>& buffer, std::size_t offset,
               std::size_t expectBytes) {
  const dicom::CheckedFile checked = checkElements(file);
  if (!checked.hasPixelData) throw FormatError(file, "has no Pixel Data");
  const bool encapsulated = checked.fragments;
  const std::size_t end = checked.end;
  checkImageHeader(file);
  gdcm::ImageReader reader;
  // Elements after the pixels (padding, signatures) are not needed and could claim any length:
  // GDCM reads the file only up to the end of its pixel data.
  std::ifstream whole;
  std::istringstream head;
  std::error_code ec;
  if (end < fs::file_size(file, ec)) {
    std::string bytes(end, '\0');
    whole.open(file, std::ios::binary);
    if (!whole.read(bytes.data(), std::streamsize(end)))
      throw FormatError(file, "cannot read its first " + std::to_string(end) + " bytes");
    head.str(std::move(bytes));
    if (encapsulated) {
      checkCompressedStart(file, &head);
      head.clear();
      head.seekg(0);
    }
    reader.SetStream(head);
  } else {
    if (encapsulated) checkCompressedStart(file, nullptr);
    reader.SetFileName(file.c_str());
  }
  if (!reader.Read())
    throw FormatError(file, "GDCM cannot read it as a DICOM image (truncated or corrupt)");
  const gdcm::Image& image = reader.GetImage();
  Decoded d;
  d.stored = storedOf(image.GetPixelFormat(), file);
  const unsigned* dims = image.GetDimensions();
  const unsigned n = image.GetNumberOfDimensions();
  for (unsigned i = 0; i < std::min(n, 3u); ++i) d.dims[i] = dims[i];
  for (int i = 0; i < 3; ++i) d.spacing[i] = image.GetSpacing(unsigned(i));
  if (const double* cosines = image.GetDirectionCosines())
    std::copy(cosines, cosines + 6, d.cosines);
  if (const double* origin = image.GetOrigin()) std::copy(origin, origin + 3, d.origin);
  d.slope = image.GetSlope(), d.intercept = image.GetIntercept();
  if (!std::isfinite(d.slope) || !std::isfinite(d.intercept) || d.slope == 0)
    throw FormatError(file, "Rescale Slope " + fixed(d.slope, 6) + " / Intercept " +
                                fixed(d.intercept, 6) + " cannot give values");
  const std::size_t need = std::size_t(d.dims[0]) * d.dims[1] * d.dims[2] * storedBytes(d.stored);
  if (expectBytes && need != expectBytes)
    throw FormatError(file, "holds " + std::to_string(d.dims[0]) + "x" + std::to_string(d.dims[1]) +
                                " pixels of " + std::to_string(storedBytes(d.stored)) +
                                " bytes where the series' first slice has " +
                                std::to_string(expectBytes) + " bytes");
  const gdcm::DataElement& pixels = image.GetDataElement();
  if (image.GetTransferSyntax().IsEncapsulated()) {
    // Compressed pixels: a few bytes must not make us allocate gigabytes. Lossless codecs shrink
    // CT by 2-4x; even a blank slice stays under the 1 MiB allowed on top of 10000x.
    const gdcm::SequenceOfFragments* fragments = pixels.GetSequenceOfFragments();
    const std::size_t have = fragments ? std::size_t(fragments->ComputeByteLength()) : 0;
    if (need > have * 10000 + (std::size_t(1) << 20))
      throw FormatError(file, "claims " + std::to_string(need) + " bytes of pixels from " +
                                  std::to_string(have) + " bytes of compressed data");
  } else {
    const gdcm::ByteValue* bv = pixels.GetByteValue();
    const std::size_t have = bv ? std::size_t(bv->GetLength()) : 0;
    // DICOM pads values to an even length: one byte more is not an error.
    if (have < need || have > need + 1)
      throw FormatError(file, "its pixel data holds " + std::to_string(have) + " bytes; " +
                                  std::to_string(d.dims[0]) + "x" + std::to_string(d.dims[1]) +
                                  (d.dims[2] > 1 ? "x" + std::to_string(d.dims[2]) : "") +
                                  " pixels of " + std::to_string(storedBytes(d.stored)) +
                                  " bytes need " + std::to_string(need));
  }
  if (image.GetBufferLength() != need)
    throw FormatError(file, "GDCM decodes " + std::to_string(image.GetBufferLength()) +
                                " bytes of pixels where " + std::to_string(need) + " are needed");
  if (buffer.size() < offset + need) buffer.resize(offset + need);
  if (!image.GetBuffer(reinterpret_cast<char*>(buffer.data() + offset)))
    throw FormatError(file, std::string("GDCM cannot decode its pixel data (transfer syntax ") +
                                image.GetTransferSyntax().GetString() + ")");
  return d;
}

bool integral(double v) { return std::abs(v - std::round(v)) < 1e-9; }

// The stored values of every slice rescaled into a volume of the smallest type that holds them.
Volume rescaled(std::vector<std::byte> stored, Stored type, glm::ivec3 dims, glm::dvec3 spacing,
                const std::vector<Decoded>& slices) {
  const std::size_t sliceVoxels = std::size_t(dims.x) * std::size_t(dims.y);
  const std::size_t perSlice =
      slices.size() == std::size_t(dims.z) ? sliceVoxels : sliceVoxels * dims.z;
  bool identity = true, whole = true;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  dispatchStored(type, [&](auto t) {
    using T = decltype(t);
    const T* v = reinterpret_cast<const T*>(stored.data());
    for (std::size_t s = 0; s < slices.size(); ++s) {
      const auto [mn, mx] = std::minmax_element(v + s * perSlice, v + (s + 1) * perSlice);
      const double a = double(*mn) * slices[s].slope + slices[s].intercept;
      const double b = double(*mx) * slices[s].slope + slices[s].intercept;
      lo = std::min({lo, a, b}), hi = std::max({hi, a, b});
      identity = identity && slices[s].slope == 1 && slices[s].intercept == 0;
      whole = whole && integral(slices[s].slope) && integral(slices[s].intercept);
    }
  });
  Volume v;
  v.dims = dims, v.spacing = spacing;
  if (identity && (type == Stored::U8 || type == Stored::U16 || type == Stored::I16)) {
    v.type = type == Stored::U8    ? ScalarType::UInt8
             : type == Stored::U16 ? ScalarType::UInt16
                                   : ScalarType::Int16;
    v.data = std::move(stored);
    v.data.resize(v.voxelCount() * scalarBytes(v.type));
    v.computeRange();
    return v;
  }
  v.type = whole && lo >= -32768 && hi <= 32767 ? ScalarType::Int16 : ScalarType::Float32;
  const std::size_t count = sliceVoxels * std::size_t(dims.z);
  // The same size in and out (16-bit stored, int16 out): converted in place.
  const bool inPlace = scalarBytes(v.type) == storedBytes(type);
  std::vector<std::byte> out;
  if (!inPlace) out.resize(count * scalarBytes(v.type));
  std::byte* dst = inPlace ? stored.data() : out.data();
  dispatchStored(type, [&](auto t) {
    using T = decltype(t);
    const T* src = reinterpret_cast<const T*>(stored.data());
    for (std::size_t s = 0; s < slices.size(); ++s) {
      const double a = slices[s].slope, b = slices[s].intercept;
      for (std::size_t i = s * perSlice; i < (s + 1) * perSlice; ++i) {
        const double value = double(src[i]) * a + b;
        if (v.type == ScalarType::Int16) {
          const auto q = std::int16_t(std::lround(value));
          std::memcpy(dst + i * 2, &q, 2);
        } else {
          const auto f = float(value);
          std::memcpy(dst + i * 4, &f, 4);
        }
      }
    }
  });
  v.data = inPlace ? std::move(stored) : std::move(out);
  v.data.resize(count * scalarBytes(v.type));
  v.computeRange();
  return v;
}

Volume readMultiFrame(const SliceHeader& h) {
  std::vector<std::byte> stored;
  const Decoded d = decode(h.file, stored, 0, 0);
  const glm::ivec3 dims(int(d.dims[0]), int(d.dims[1]), int(d.dims[2]));
  checkDims(dims, h.file);
  glm::dvec3 spacing = d.spacing;
  for (int i = 0; i < 3; ++i)
    if (!(spacing[i] > 0) || !std::isfinite(spacing[i])) spacing[i] = 1;
  Volume v = rescaled(std::move(stored), d.stored, dims, spacing, {d});
  v.orientation = orientationOf(d.cosines, d.origin);
  return v;
}

// Refuses colour images; returns the one multi-frame file of the series (nullptr when its files
// are single slices), refusing a series that mixes several files with a multi-frame one.
const SliceHeader* greyscaleMultiFrame(const std::vector<SliceHeader>& slices,
                                       const std::string& path, const std::string& name) {
  for (const SliceHeader& s : slices)
    if (s.samples != 1)
      throw FormatError(s.file, "is a colour image (" + std::to_string(s.samples) +
                                    " samples per pixel); voxwall reads greyscale DICOM");
  for (const SliceHeader& s : slices)
    if (s.frames > 1) {
      if (slices.size() > 1)
        throw FormatError(path, name + " holds " + std::to_string(slices.size()) +
                                    " files of which " + s.file +
                                    " has several frames; read one multi-frame file at a time");
      return &s;
    }
  return nullptr;
}

// The slices' pixels, decoded in slice order into `stored`, each checked against the header's
// size and the first slice's type.
std::vector<Decoded> decodeSlices(const std::vector<SliceHeader>& slices, glm::ivec3 dims,
                                  std::vector<std::byte>& stored) {
  std::vector<Decoded> decoded;
  decoded.reserve(slices.size());
  std::size_t sliceBytes = 0;
  for (std::size_t z = 0; z < slices.size(); ++z) {
    decoded.push_back(decode(slices[z].file, stored, z * sliceBytes, sliceBytes));
    const Decoded& d = decoded.back();
    if (d.dims[0] != unsigned(dims.x) || d.dims[1] != unsigned(dims.y) || d.dims[2] != 1)
      throw FormatError(slices[z].file, "decodes to " + std::to_string(d.dims[0]) + "x" +
                                            std::to_string(d.dims[1]) + " where its header says " +
                                            std::to_string(dims.x) + "x" + std::to_string(dims.y));
    if (d.stored != decoded.front().stored)
      throw FormatError(slices[z].file, "stores its pixels in another type than " +
                                            slices.front().file + " of the same series");
    if (z == 0) {
      sliceBytes = std::size_t(dims.x) * std::size_t(dims.y) * storedBytes(d.stored);
      stored.reserve(sliceBytes * slices.size());
    }
  }
  return decoded;
}

// Voxels stay in stored order; the orientation says where they lie (DICOM's patient space is
// voxwall's LPS): rows, columns, then the normal the sorted slices were placed along (a tilt
// undone or refused), or a single slice's own orientation and position.
void placeInPatient(Volume& v, const std::vector<SliceHeader>& slices, const SliceAxes& axes,
                    const std::string& path, const std::string& name, const DicomOptions& options) {
  const SliceHeader& first = slices.front();
  if (slices.size() > 1) {
    v.orientation.direction = glm::dmat3(axes.row, axes.column, axes.normal);
    v.orientation.origin = first.ipp;
    undoGantryTilt(v, slices, axes, path, name, options.resampleTilt);
  } else if (first.orientation.size() == 6 && first.position.size() == 3) {
    v.orientation = orientationOf(first.orientation.data(), first.position.data());
  }
}

// An enhanced multi-frame file (functional groups): its frames grouped into images, the one
// picked (options.image, or the only one) placed as the slices of a series are, each frame with
// its own rescale. Returns nothing for a multi-frame file without functional groups.
std::optional<Volume> readEnhanced(const SliceHeader& h, const std::string& path,
                                   const DicomOptions& options) {
  const std::vector<dicom::FrameGeometry> frames = dicom::enhancedFrames(h.file, h.frames);
  if (frames.empty()) return std::nullopt;
  std::vector<std::string> images;  // in order of their first frame
  std::vector<std::vector<int>> members;
  for (int f = 0; f < int(frames.size()); ++f) {
    const auto it = std::find(images.begin(), images.end(), frames[std::size_t(f)].image);
    if (it == images.end()) {
      images.push_back(frames[std::size_t(f)].image);
      members.push_back({f});
    } else {
      members[std::size_t(it - images.begin())].push_back(f);
    }
  }
  if (images.size() > 1 && options.image == 0) {
    std::string list;
    for (std::size_t i = 0; i < images.size(); ++i)
      list += (i ? "; " : "") + std::to_string(i + 1) + ": " +
              frames[std::size_t(members[i].front())].label + " (" +
              std::to_string(members[i].size()) + " frames)";
    throw FormatError(h.file, "holds " + std::to_string(images.size()) + " images in its " +
                                  std::to_string(frames.size()) + " frames (" + list +
                                  "); read one with --dicom-image N");
  }
  if (options.image < 0 || std::size_t(options.image) > images.size())
    throw FormatError(h.file, "holds " + std::to_string(images.size()) +
                                  (images.size() == 1 ? " image" : " images") + "; --dicom-image " +
                                  std::to_string(options.image) + " is not one of them");
  const std::vector<int>& picked = members[std::size_t(std::max(options.image, 1) - 1)];
  std::vector<SliceHeader> slices;
  for (const int f : picked) {
    const dicom::FrameGeometry& g = frames[std::size_t(f)];
    SliceHeader s = h;
    s.file = h.file + " (frame " + std::to_string(f + 1) + ")";
    s.frames = 1, s.frame = f;
    s.position = g.position, s.orientation = g.orientation;
    s.decimals = g.positionDecimals;
    slices.push_back(std::move(s));
  }
  const std::string name =
      images.size() > 1 ? h.file + " image " + std::to_string(options.image) : h.file;
  const SliceAxes axes = placeSlices(slices, path, name, options);
  std::vector<std::byte> all;
  const Decoded d = decode(h.file, all, 0, 0);
  if (d.dims[0] != unsigned(h.columns) || d.dims[1] != unsigned(h.rows) ||
      d.dims[2] != unsigned(frames.size()))
    throw FormatError(h.file, "decodes to " + std::to_string(d.dims[0]) + "x" +
                                  std::to_string(d.dims[1]) + "x" + std::to_string(d.dims[2]) +
                                  " where its header says " + std::to_string(h.columns) + "x" +
                                  std::to_string(h.rows) + "x" + std::to_string(frames.size()));
  const glm::ivec3 dims(h.columns, h.rows, int(slices.size()));
  checkDims(dims, path);
  const std::size_t frameBytes =
      std::size_t(h.columns) * std::size_t(h.rows) * storedBytes(d.stored);
  std::vector<std::byte> stored(frameBytes * slices.size());
  std::vector<Decoded> perSlice;
  for (std::size_t z = 0; z < slices.size(); ++z) {
    const dicom::FrameGeometry& g = frames[std::size_t(slices[z].frame)];
    std::memcpy(stored.data() + z * frameBytes,
                all.data() + std::size_t(slices[z].frame) * frameBytes, frameBytes);
    Decoded one = d;
    if (g.rescaled) one.slope = g.slope, one.intercept = g.intercept;
    perSlice.push_back(one);
  }
  all = {};
  // DICOM's Pixel Spacing is rows apart, then columns apart: y, then x.
  const dicom::FrameGeometry& first = frames[std::size_t(slices.front().frame)];
  glm::dvec3 spacing = d.spacing;
  for (const int f : picked)
    if (frames[std::size_t(f)].pixelSpacing != first.pixelSpacing)
      throw FormatError(h.file, "frame " + std::to_string(f + 1) +
                                    " has another Pixel Spacing than frame " +
                                    std::to_string(slices.front().frame + 1) + " of " + name);
  if (first.pixelSpacing.size() == 2)
    spacing.x = first.pixelSpacing[1], spacing.y = first.pixelSpacing[0];
  for (int i = 0; i < 2; ++i)
    if (!(spacing[i] > 0) || !std::isfinite(spacing[i]))
      throw FormatError(h.file, "has no usable Pixel Spacing (" + fixed(spacing[i], 4) + ")");
  if (slices.size() > 1)
    spacing.z = fittedGap(slices);
  else
    spacing.z = first.sliceThickness > 0 ? first.sliceThickness : 1;
  Volume v = rescaled(std::move(stored), d.stored, dims, spacing, perSlice);
  placeInPatient(v, slices, axes, path, name, options);
  return v;
}

}  // namespace

bool isDicomFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec) && (isDicomDirName(path) || startsAsDicom(path));
}

bool isDicomFolder(const std::string& path) {
  std::error_code ec;
  int looked = 0;
  for (fs::recursive_directory_iterator it(path, fs::directory_options::skip_permission_denied, ec),
       end;
       !ec && it != end && looked < 256; it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    if (isDicomDirName(it->path()) || startsAsDicom(it->path())) return true;
    ++looked;
  }
  return false;
}

std::vector<DicomSeriesInfo> listDicomSeries(const std::string& path) {
  std::vector<DicomSeriesInfo> out;
  for (auto& [uid, s] : scanSeries(path)) out.push_back(s.info);
  return out;
}

Volume readDicom(const std::string& path, const DicomOptions& options) {
  const auto all = scanSeries(path);
  const Series& series = pickSeries(all, path, options);
  std::vector<SliceHeader> slices = series.slices;
  const std::string name = series.info.uid.empty() ? path : "series " + series.info.uid;
  if (const SliceHeader* multiFrame = greyscaleMultiFrame(slices, path, name)) {
    if (auto enhanced = readEnhanced(*multiFrame, path, options)) return std::move(*enhanced);
    if (options.image > 1)
      throw FormatError(multiFrame->file, "holds one image; --dicom-image " +
                                              std::to_string(options.image) +
                                              " is not one of them");
    return readMultiFrame(*multiFrame);
  }
  if (options.image > 1)
    throw FormatError(path, name +
                                " is a series of single-frame files, one image; "
                                "--dicom-image " +
                                std::to_string(options.image) + " is not one of them");

  const SliceAxes axes = placeSlices(slices, path, name, options);
  const SliceHeader& first = slices.front();
  const glm::ivec3 dims(first.columns, first.rows, int(slices.size()));
  checkDims(dims, path);
  std::vector<std::byte> stored;
  const std::vector<Decoded> decoded = decodeSlices(slices, dims, stored);

  glm::dvec3 spacing = decoded.front().spacing;
  for (int i = 0; i < 2; ++i)
    if (!(spacing[i] > 0) || !std::isfinite(spacing[i]))
      throw FormatError(first.file, "has no usable Pixel Spacing (" + fixed(spacing[i], 4) + ")");
  if (slices.size() > 1)
    spacing.z = fittedGap(slices);
  else if (!(spacing.z > 0) || !std::isfinite(spacing.z))
    spacing.z = 1;

  Volume v = rescaled(std::move(stored), decoded.front().stored, dims, spacing, decoded);
  placeInPatient(v, slices, axes, path, name, options);
  return v;
}

}  // namespace voxwall::codec
