// DICOM series through GDCM: the files of a folder grouped by series, one series' slices sorted
// along their normal and checked for the gaps, sizes and orientations a volume needs, their
// pixels decoded by GDCM (any transfer syntax it decodes) and rescaled to their real values.
#include <gdcmImageReader.h>
#include <gdcmReader.h>
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
#include <sstream>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {
namespace {

namespace fs = std::filesystem;

// At most this many files are looked at under one folder: a folder that holds more is refused
// rather than read for minutes.
constexpr std::size_t kMaxFiles = 200000;

const gdcm::Tag kSeriesUid(0x0020, 0x000e), kSeriesDescription(0x0008, 0x103e),
    kModality(0x0008, 0x0060), kRows(0x0028, 0x0010), kColumns(0x0028, 0x0011),
    kPosition(0x0020, 0x0032), kOrientation(0x0020, 0x0037), kFrames(0x0028, 0x0008),
    kSamples(0x0028, 0x0002), kPixelData(0x7fe0, 0x0010);

// GDCM reports problems on stderr through its trace; the reader reports them itself, in one line.
void quietGdcm() {
  static std::once_flag once;
  std::call_once(once, [] {
    gdcm::Trace::SetDebug(false);
    gdcm::Trace::SetWarning(false);
    gdcm::Trace::SetError(false);
  });
}

std::string trimmed(const char* value) {
  if (!value) return {};
  std::string s(value);
  static const std::string blank(" \t\r\n\0", 5);  // DICOM pads with spaces (UIDs with NUL)
  const auto first = s.find_first_not_of(blank);
  if (first == std::string::npos) return {};
  return s.substr(first, s.find_last_not_of(blank) - first + 1);
}

// "a\b\c" as numbers; empty when any of them is not a finite number.
std::vector<double> numbersOf(const std::string& text) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, '\\')) {
    try {
      std::size_t used = 0;
      const double v = std::stod(item, &used);
      if (!std::isfinite(v) || trimmed(item.c_str() + used).size()) return {};
      out.push_back(v);
    } catch (const std::exception&) {
      return {};
    }
  }
  return out;
}

int intOf(const std::string& text, int fallback) {
  const auto v = numbersOf(text);
  return v.size() == 1 && v[0] == std::floor(v[0]) && std::abs(v[0]) < 1e9 ? int(v[0]) : fallback;
}

std::string fixed(double v, int digits = 2) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

bool startsAsDicom(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  char head[132];
  return in.read(head, sizeof head) && std::memcmp(head + 128, "DICM", 4) == 0;
}

// Debian's GDCM is built with its assertions on, and its reader of the File Meta Information
// (group 0002, always explicit VR little endian) asserts, aborting the program, on a sequence, an
// undefined length or a value cut short there. Those elements are walked here first (only their
// lengths, not their meaning) so that such a file is refused instead.
void checkMetaGroup(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(file, ec);
  if (ec || !in) throw FormatError(file, "cannot read it");
  std::uint64_t at = 132;  // after the preamble and "DICM"
  auto bytes = [&](std::uint64_t offset, std::size_t n, unsigned char* out) {
    if (offset + n > size) return false;
    in.seekg(std::streamoff(offset));
    return bool(in.read(reinterpret_cast<char*>(out), std::streamsize(n)));
  };
  for (int elements = 0; elements < 1000; ++elements) {
    unsigned char head[8];
    if (!bytes(at, 2, head) || (head[0] | head[1] << 8) != 0x0002) return;  // the meta group ended
    if (!bytes(at, 8, head)) throw FormatError(file, "its File Meta Information is cut short");
    const char vr[3] = {char(head[4]), char(head[5]), 0};
    const std::string v(vr);
    const bool long32 = v == "OB" || v == "OW" || v == "OF" || v == "OD" || v == "OL" ||
                        v == "OV" || v == "SQ" || v == "UN" || v == "UT" || v == "UC" ||
                        v == "UR" || v == "SV" || v == "UV";
    std::uint64_t length = 0, header = 8;
    if (long32) {
      unsigned char l[4];
      if (!bytes(at + 8, 4, l)) throw FormatError(file, "its File Meta Information is cut short");
      length = std::uint64_t(l[0]) | std::uint64_t(l[1]) << 8 | std::uint64_t(l[2]) << 16 |
               std::uint64_t(l[3]) << 24;
      header = 12;
    } else {
      length = std::uint64_t(head[6]) | std::uint64_t(head[7]) << 8;
    }
    if (v == "SQ" || length == 0xffffffffu)
      throw FormatError(file, "its File Meta Information holds a sequence or an undefined length");
    if (at + header + length > size)
      throw FormatError(file,
                        "an element of its File Meta Information runs past the end of the "
                        "file");
    at += header + length;
  }
  throw FormatError(file, "its File Meta Information holds more than 1000 elements");
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

// What the scanner found of one image file.
struct SliceHeader {
  std::string file, series;
  int columns = 0, rows = 0, frames = 1, samples = 1;
  std::vector<double> position, orientation;
  glm::dvec3 ipp{0};
  double along = 0;  // ipp projected on the slice normal
};

struct Series {
  DicomSeriesInfo info;
  std::vector<SliceHeader> slices;
};

// The image files under `path` grouped by series (files without Rows/Columns, such as reports
// and presentation states, are not images and are left out).
std::map<std::string, Series> scanSeries(const std::string& path) {
  quietGdcm();
  const std::vector<std::string> files = dicomFilesOf(path);
  for (const std::string& f : files) checkMetaGroup(f);
  gdcm::Scanner scanner;
  for (const gdcm::Tag& t : {kSeriesUid, kSeriesDescription, kModality, kRows, kColumns, kPosition,
                             kOrientation, kFrames, kSamples})
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
    h.position = numbersOf(value(kPosition));
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

// Where the file's Pixel Data ends, found by walking its elements without reading their values
// (GDCM allocates what an element claims when it reads one: a corrupt length would cost
// gigabytes). Refuses a file cut short, or one whose elements run past its end.
std::size_t pixelDataEnd(const std::string& file, bool& encapsulated) {
  gdcm::Reader walk;
  walk.SetFileName(file.c_str());
  if (!walk.ReadSelectedTags({kPixelData}, false))
    throw FormatError(file, "GDCM cannot read it as DICOM (corrupt header)");
  if (!walk.GetFile().GetDataSet().FindDataElement(kPixelData))
    throw FormatError(file,
                      "has no Pixel Data, or an element before it claims more bytes than "
                      "the file holds");
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(file, ec);
  const std::size_t end = walk.GetStreamCurrentPosition();
  if (ec || end > size)
    throw FormatError(file, "is cut short: its pixel data ends at byte " + std::to_string(end) +
                                " but the file has " + std::to_string(size) + " bytes");
  encapsulated = walk.GetFile().GetHeader().GetDataSetTransferSyntax().IsEncapsulated();
  return end;
}

// GDCM's image reader looks into compressed pixel data as it reads a file: handed a JPEG
// fragment that is not JPEG, it retried for 23 s and 3.2 GB on three 1 KiB files (found by the
// DICOM fuzz target). So a compressed file is first read plainly (no decoding), and its first
// fragment must start as its transfer syntax's stream does: JPEG and JPEG-LS with SOI, JPEG 2000
// with a codestream or a JP2 box, RLE with a segment count of 1 to 15.
void checkCompressedStart(const std::string& file, std::istream* stream) {
  gdcm::Reader plain;
  if (stream)
    plain.SetStream(*stream);
  else
    plain.SetFileName(file.c_str());
  if (!plain.Read()) throw FormatError(file, "GDCM cannot read it as DICOM (corrupt)");
  const gdcm::TransferSyntax syntax = plain.GetFile().GetHeader().GetDataSetTransferSyntax();
  if (!syntax.IsEncapsulated()) return;
  const std::string ts = syntax.GetString() ? syntax.GetString() : "";
  const gdcm::DataSet& ds = plain.GetFile().GetDataSet();
  const gdcm::SequenceOfFragments* fragments =
      ds.FindDataElement(kPixelData) ? ds.GetDataElement(kPixelData).GetSequenceOfFragments()
                                     : nullptr;
  const gdcm::ByteValue* first = fragments && fragments->GetNumberOfFragments() > 0
                                     ? fragments->GetFragment(0).GetByteValue()
                                     : nullptr;
  const auto* b = first ? reinterpret_cast<const unsigned char*>(first->GetPointer()) : nullptr;
  const std::size_t n = first && b ? std::size_t(first->GetLength()) : 0;
  bool starts = n > 0;
  if (ts.rfind("1.2.840.10008.1.2.4.9", 0) == 0)
    starts = (n >= 4 && b[0] == 0xff && b[1] == 0x4f && b[2] == 0xff && b[3] == 0x51) ||
             (n >= 8 && b[4] == 'j' && b[5] == 'P' && b[6] == ' ' && b[7] == ' ');
  else if (ts.rfind("1.2.840.10008.1.2.4.", 0) == 0)
    starts = n >= 2 && b[0] == 0xff && b[1] == 0xd8;
  else if (ts == "1.2.840.10008.1.2.5")
    starts = n >= 64 && b[0] >= 1 && b[0] <= 15 && b[1] == 0 && b[2] == 0 && b[3] == 0;
  if (!starts)
    throw FormatError(
        file, "its compressed pixel data does not start as transfer syntax " + ts + " does");
}

Decoded decode(const std::string& file, std::vector<std::byte>& buffer, std::size_t offset,
               std::size_t expectBytes) {
  bool encapsulated = false;
  const std::size_t end = pixelDataEnd(file, encapsulated);
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

// Moves slice z of `v` by (dx, dy) voxels (bilinear, the lowest value outside the slice), which
// undoes a gantry tilt's shear.
void shiftSlice(Volume& v, int z, double dx, double dy) {
  dispatchScalar(v.type, [&](auto t) {
    using T = decltype(t);
    const int w = v.dims.x, h = v.dims.y;
    T* slice = v.as<T>().data() + std::size_t(z) * std::size_t(w) * std::size_t(h);
    const std::vector<T> src(slice, slice + std::size_t(w) * std::size_t(h));
    const double outside = v.valueMin;
    auto at = [&](int x, int y) {
      return x < 0 || y < 0 || x >= w || y >= h ? outside
                                                : double(src[std::size_t(y) * w + std::size_t(x)]);
    };
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double sx = x - dx, sy = y - dy;
        const int x0 = int(std::floor(sx)), y0 = int(std::floor(sy));
        const double fx = sx - x0, fy = sy - y0;
        const double value = (at(x0, y0) * (1 - fx) + at(x0 + 1, y0) * fx) * (1 - fy) +
                             (at(x0, y0 + 1) * (1 - fx) + at(x0 + 1, y0 + 1) * fx) * fy;
        slice[std::size_t(y) * w + std::size_t(x)] =
            std::is_floating_point_v<T> ? T(value) : T(std::lround(value));
      }
  });
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

  for (const SliceHeader& s : slices)
    if (s.frames > 1) {
      if (slices.size() > 1)
        throw FormatError(path, name + " holds " + std::to_string(slices.size()) +
                                    " files of which " + s.file +
                                    " has several frames; read one multi-frame file at a time");
      return readMultiFrame(s);
    }
  for (const SliceHeader& s : slices)
    if (s.samples != 1)
      throw FormatError(s.file, "is a colour image (" + std::to_string(s.samples) +
                                    " samples per pixel); voxwall reads greyscale DICOM");

  // Every slice the same size and orientation, at a position of its own along the normal.
  const SliceHeader& first = slices.front();
  for (const SliceHeader& s : slices)
    if (s.columns != first.columns || s.rows != first.rows)
      throw FormatError(s.file, "is " + std::to_string(s.columns) + "x" + std::to_string(s.rows) +
                                    " but " + first.file + " of the same series is " +
                                    std::to_string(first.columns) + "x" +
                                    std::to_string(first.rows));
  glm::dvec3 row(1, 0, 0), column(0, 1, 0), normal(0, 0, 1);
  if (slices.size() > 1) {
    for (const SliceHeader& s : slices) {
      if (s.position.size() != 3)
        throw FormatError(s.file, "has no Image Position (Patient) to place the slice by");
      if (s.orientation.size() != 6)
        throw FormatError(s.file, "has no Image Orientation (Patient) to place the slice by");
    }
    const auto& o = first.orientation;
    row = {o[0], o[1], o[2]}, column = {o[3], o[4], o[5]};
    if (std::abs(glm::length(row) - 1) > 1e-3 || std::abs(glm::length(column) - 1) > 1e-3 ||
        std::abs(glm::dot(row, column)) > 1e-3)
      throw FormatError(first.file,
                        "its Image Orientation (Patient) is not two perpendicular unit "
                        "vectors");
    normal = glm::normalize(glm::cross(row, column));
    for (SliceHeader& s : slices) {
      for (int i = 0; i < 6; ++i)
        if (std::abs(s.orientation[std::size_t(i)] - o[std::size_t(i)]) > 1e-3)
          throw FormatError(s.file, "is oriented differently from " + first.file +
                                        " in the same series (Image Orientation (Patient))");
      s.ipp = {s.position[0], s.position[1], s.position[2]};
      s.along = glm::dot(s.ipp, normal);
    }
    std::stable_sort(slices.begin(), slices.end(),
                     [](const SliceHeader& a, const SliceHeader& b) { return a.along < b.along; });
    std::vector<double> gaps;
    for (std::size_t i = 1; i < slices.size(); ++i) {
      const double gap = slices[i].along - slices[i - 1].along;
      if (gap < 1e-3)
        throw FormatError(path, slices[i - 1].file + " and " + slices[i].file + " of " + name +
                                    " lie at the same position (" + fixed(slices[i].along, 3) +
                                    " mm along the normal): several echoes, phases or times in "
                                    "one series are not read as one volume");
      gaps.push_back(gap);
    }
    std::vector<double> sorted = gaps;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2),
                     sorted.end());
    const double median = sorted[sorted.size() / 2];
    const double tolerance = std::max(0.01, 0.01 * median);
    for (std::size_t i = 0; i < gaps.size(); ++i) {
      if (std::abs(gaps[i] - median) <= tolerance) continue;
      const double ratio = gaps[i] / median;
      const std::string between = slices[i].file + " and " + slices[i + 1].file;
      if (std::round(ratio) >= 2 && std::abs(gaps[i] - std::round(ratio) * median) <= tolerance) {
        const int missing = int(std::round(ratio)) - 1;
        throw FormatError(
            path, std::to_string(missing) + (missing == 1 ? " slice is" : " slices are") +
                      " missing from " + name + " between " + between + ": " + fixed(gaps[i], 3) +
                      " mm apart where the others are " + fixed(median, 3) + " mm");
      }
      throw FormatError(path, name + " has unequal gaps between its slices: " + fixed(gaps[i], 3) +
                                  " mm between " + between + " where the others are " +
                                  fixed(median, 3) + " mm");
    }
  }

  // The pixels, decoded in slice order.
  const glm::ivec3 dims(first.columns, first.rows, int(slices.size()));
  checkDims(dims, path);
  std::vector<std::byte> stored;
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
      throw FormatError(slices[z].file, "stores its pixels in another type than " + first.file +
                                            " of the same series");
    if (z == 0) {
      sliceBytes = std::size_t(dims.x) * std::size_t(dims.y) * storedBytes(d.stored);
      stored.reserve(sliceBytes * slices.size());
    }
  }

  glm::dvec3 spacing = decoded.front().spacing;
  for (int i = 0; i < 2; ++i)
    if (!(spacing[i] > 0) || !std::isfinite(spacing[i]))
      throw FormatError(first.file, "has no usable Pixel Spacing (" + fixed(spacing[i], 4) + ")");
  if (slices.size() > 1)
    spacing.z = (slices.back().along - slices.front().along) / double(slices.size() - 1);
  else if (!(spacing.z > 0) || !std::isfinite(spacing.z))
    spacing.z = 1;

  Volume v = rescaled(std::move(stored), decoded.front().stored, dims, spacing, decoded);
  // Voxels stay in stored order; the orientation says where they lie (DICOM's patient space is
  // voxwall's LPS): rows, columns, then the normal the slices were sorted along.
  if (slices.size() > 1) {
    v.orientation.direction = glm::dmat3(row, column, normal);
    v.orientation.origin = slices.front().ipp;
  } else if (first.orientation.size() == 6 && first.position.size() == 3) {
    v.orientation = orientationOf(first.orientation.data(), first.position.data());
  }

  // A gantry tilt: each slice's position moves in the slice's plane as well as along its normal.
  if (slices.size() > 1) {
    std::vector<glm::dvec2> shifts;
    double worst = 0;
    for (const SliceHeader& s : slices) {
      const glm::dvec3 offset = s.ipp - slices.front().ipp;
      const glm::dvec3 inPlane = offset - glm::dot(offset, normal) * normal;
      shifts.push_back({glm::dot(inPlane, row) / spacing.x, glm::dot(inPlane, column) / spacing.y});
      worst = std::max({worst, std::abs(shifts.back().x), std::abs(shifts.back().y)});
    }
    if (worst > 0.1) {
      const glm::dvec3 last = slices.back().ipp - slices.front().ipp;
      const double along = glm::dot(last, normal);
      const double degrees =
          std::atan2(glm::length(last - along * normal), along) * 180.0 / 3.14159265358979323846;
      if (!options.resampleTilt)
        throw FormatError(path, name + " is sheared by a gantry tilt of " + fixed(degrees, 1) +
                                    " degrees (its slices move " + fixed(worst, 1) +
                                    " voxels across the series); --resample-tilt resamples it "
                                    "onto a box");
      for (int z = 0; z < dims.z; ++z)
        shiftSlice(v, z, shifts[std::size_t(z)].x, shifts[std::size_t(z)].y);
      v.computeRange();
    }
  }
  return v;
}

}  // namespace voxwall::codec
