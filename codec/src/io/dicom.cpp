// DICOM series through GDCM: the files of a folder grouped by series, one series' slices sorted
// along their normal and checked for the gaps, sizes and orientations a volume needs, their
// pixels decoded by GDCM (any transfer syntax it decodes) and rescaled to their real values.
#include <gdcmDicts.h>
#include <gdcmGlobal.h>
#include <gdcmImageReader.h>
#include <gdcmReader.h>
#include <gdcmScanner.h>
#include <gdcmSequenceOfFragments.h>
#include <gdcmSequenceOfItems.h>
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

// Little-endian 16- and 32-bit values of a file's bytes (the walks below read DICOM's own
// little-endian encodings).
unsigned le16(const unsigned char* b) { return unsigned(b[0]) | unsigned(b[1]) << 8; }
std::uint32_t le32(const unsigned char* b) {
  return std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 | std::uint32_t(b[2]) << 16 |
         std::uint32_t(b[3]) << 24;
}

// Whether `vr` is a value representation DICOM defines (PS3.5 6.2).
bool isDicomVr(const std::string& vr) {
  static const std::string kVrs =
      "AE AS AT CS DA DS DT FL FD IS LO LT OB OD OF OL OV OW PN SH SL SQ SS ST SV TM UC UI UL UN "
      "UR US UT UV";
  const std::size_t at = kVrs.find(vr);
  return vr.size() == 2 && at != std::string::npos && at % 3 == 0;
}

// Debian's GDCM is built with its assertions on, and its reader of the File Meta Information
// (group 0002, always explicit VR little endian) asserts, aborting the program, on a sequence, an
// undefined length or a value cut short there. Those elements are walked here first (only their
// lengths, not their meaning) so that such a file is refused instead. Returns where the data set
// starts; `transferSyntax` receives the UID of (0002,0010).
std::uint64_t checkMetaGroup(const std::string& file, std::string& transferSyntax) {
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
    if (!bytes(at, 2, head) || le16(head) != 0x0002) {  // the group ended
      // GDCM asserts when the file ends there (found by the DICOM fuzz target).
      if (at + 8 > size)
        throw FormatError(file, "ends after its File Meta Information (it has no data set)");
      return at;
    }
    if (!bytes(at, 8, head)) throw FormatError(file, "its File Meta Information is cut short");
    const char vr[3] = {char(head[4]), char(head[5]), 0};
    const std::string v(vr);
    // GDCM's meta reader asserts on a VR it does not know (found by the DICOM fuzz target).
    if (!isDicomVr(v))
      throw FormatError(file,
                        "its File Meta Information has an element whose value representation "
                        "DICOM does not define");
    const bool long32 = v == "OB" || v == "OW" || v == "OF" || v == "OD" || v == "OL" ||
                        v == "OV" || v == "SQ" || v == "UN" || v == "UT" || v == "UC" ||
                        v == "UR" || v == "SV" || v == "UV";
    std::uint64_t length = 0, header = 8;
    if (long32) {
      unsigned char l[4];
      if (!bytes(at + 8, 4, l)) throw FormatError(file, "its File Meta Information is cut short");
      length = le32(l);
      header = 12;
    } else {
      length = le16(head + 6);
    }
    if (v == "SQ" || length == 0xffffffffu)
      throw FormatError(file, "its File Meta Information holds a sequence or an undefined length");
    if (at + header + length > size)
      throw FormatError(file,
                        "an element of its File Meta Information runs past the end of the "
                        "file");
    if ((head[2] | head[3] << 8) == 0x0010 && length < 256) {
      std::string uid(std::size_t(length), '\0');
      in.seekg(std::streamoff(at + header));
      in.read(uid.data(), std::streamsize(length));
      while (!uid.empty() && (uid.back() == '\0' || uid.back() == ' ')) uid.pop_back();
      transferSyntax = uid;
    }
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

std::uint64_t walkToPixelData(const std::string& file, std::string* transferSyntax = nullptr);

// The image files under `path` grouped by series (files without Rows/Columns, such as reports
// and presentation states, are not images and are left out).
std::map<std::string, Series> scanSeries(const std::string& path) {
  quietGdcm();
  const std::vector<std::string> files = dicomFilesOf(path);
  std::map<std::string, std::string> syntaxOf;  // each file's transfer syntax UID
  for (const std::string& f : files) walkToPixelData(f, &syntaxOf[f]);  // before the scanner
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

// Checks that the data set's elements before `stop` (and those of their sequences) each end
// inside the file, walking their tags and lengths only (never their values or meaning): GDCM,
// reading an element whose value runs past the end, falls back to other encodings on a failed
// stream and (built with assertions) aborts the program. Found by the DICOM fuzz target: a Rows
// element claiming 53,250 bytes in a 1 KiB file.
class ElementWalk {
 public:
  ElementWalk(const std::string& file, std::uint64_t size, bool explicitVr)
      : file_(file), in_(file, std::ios::binary), size_(size), explicit_(explicitVr) {}

  // The elements from `at` until the element `stop` (at depth 0), the end of the file or, in an
  // item of undefined length, the item's delimiter; returns where the walk ended.
  std::uint64_t list(std::uint64_t at, std::uint64_t end, int depth, bool delimited,
                     std::uint32_t stop) {
    if (depth > 16) fail(at, "nests sequences more than 16 deep");
    while (at < end) {
      unsigned char h[12];
      read(at, h, 8, end);
      const std::uint32_t tag = std::uint32_t(le16(h)) << 16 | le16(h + 2);
      if (tag == 0xfffee00du && delimited) {  // the item's end
        if (le32(h + 4) != 0) fail(at, delimiterError(at));
        return at + 8;
      }
      if ((tag >> 16) == 0xfffe) fail(at, "has a misplaced item or delimiter");
      // Elements past `stop` (a file without Pixel Data) are checked like the others: GDCM's
      // scanner reads the first element past the tags it looks for.
      if (depth == 0 && tag == stop) return at;
      std::uint64_t header = 8, length = 0;
      bool sequence = false;
      if (explicit_) {
        const std::string vr{char(h[4]), char(h[5])};
        // A VR DICOM does not define sends GDCM's reader into its fallbacks for broken files,
        // which read the lengths another way (the fuzz target found one allocating 4 GB).
        if (!isDicomVr(vr))
          fail(at, "has an element (" + hex(tag) + ") at byte " + std::to_string(at) +
                       " with a value representation DICOM does not define");
        // GDCM's image helpers assert that a public element's VR is the dictionary's (found by
        // the DICOM fuzz target: Pixel Spacing stored as UT). UN fits any element.
        const gdcm::VR expected = dictionaryVr(tag);
        if (vr != "UN" && expected != gdcm::VR::INVALID &&
            !expected.Compatible(gdcm::VR(gdcm::VR::GetVRType(vr.c_str()))))
          fail(at, "has an element (" + hex(tag) + ") at byte " + std::to_string(at) +
                       " stored as " + vr + " where DICOM says " + gdcm::VR::GetVRString(expected));
        static const char* const kLong[] = {"OB", "OW", "OF", "OD", "OL", "OV", "SQ",
                                            "UN", "UT", "UC", "UR", "SV", "UV"};
        bool isLong = false;
        for (const char* v : kLong) isLong = isLong || vr == v;
        sequence = vr == "SQ";
        if (isLong) {
          read(at, h, 12, end);
          header = 12, length = le32(h + 8);
        } else {
          length = le16(h + 6);
        }
      } else {
        length = le32(h + 4);
        // Implicit VR: GDCM reads a sequence's items when its dictionary says SQ.
        sequence = dictionaryVr(tag) == gdcm::VR::SQ;
      }
      if (length == 0xffffffffu) {
        // An undefined-length UN holds implicit VR little endian elements (PS3.5 6.2.2); an
        // undefined-length OB or OW (pixel data, such as an icon's) holds fragments, whose
        // bytes are not elements.
        const bool saved = explicit_;
        const bool fragments =
            explicit_ ? !sequence && !(h[4] == 'U' && h[5] == 'N') : tag == 0x7fe00010u;
        if (explicit_ && h[4] == 'U' && h[5] == 'N') explicit_ = false;
        at = items(at + header, end, depth, true, fragments);
        explicit_ = saved;
        continue;
      }
      if (at + header + length > end)
        fail(at, "has an element (" + hex(tag) + ") at byte " + std::to_string(at) +
                     " that claims " + std::to_string(length) +
                     " bytes past the end of the file (" + std::to_string(size_) + " bytes)");
      if (sequence) items(at + header, at + header + length, depth, false, false);
      at += header + length;
    }
    if (delimited) fail(at, "ends inside a sequence (cut short)");
    return at;
  }

 private:
  // The items of a sequence from `at`: up to `end`, or (undefined length) up to its delimiter.
  // The elements in each item are walked too, unless the items are `fragments` of pixel data.
  std::uint64_t items(std::uint64_t at, std::uint64_t end, int depth, bool delimited,
                      bool fragments) {
    while (at < end) {
      unsigned char h[8];
      read(at, h, 8, end);
      const std::uint32_t tag = std::uint32_t(le16(h)) << 16 | le16(h + 2);
      const std::uint32_t length = le32(h + 4);
      if (tag == 0xfffee0ddu && delimited) {
        if (length != 0) fail(at, delimiterError(at));
        return at + 8;
      }
      if (tag != 0xfffee000u) fail(at, "has something other than an item in a sequence");
      if (length == 0xffffffffu) {
        if (fragments) fail(at, "has a pixel data fragment of undefined length");
        at = list(at + 8, end, depth + 1, true, 0);
      } else {
        if (at + 8 + length > end)
          fail(at, "has a sequence item at byte " + std::to_string(at) + " that claims " +
                       std::to_string(length) + " bytes past its end");
        if (!fragments) list(at + 8, at + 8 + length, depth + 1, false, 0);
        at += 8 + length;
      }
    }
    if (delimited) fail(at, "ends inside a sequence (cut short)");
    return at;
  }

  void read(std::uint64_t at, unsigned char* out, std::size_t n, std::uint64_t end) {
    if (at > end || n > end - at || !in_.seekg(std::streamoff(at)) ||
        !in_.read(reinterpret_cast<char*>(out), std::streamsize(n)))
      fail(at, "is cut short inside an element's header at byte " + std::to_string(at));
  }
  [[noreturn]] void fail(std::uint64_t, const std::string& what) { throw FormatError(file_, what); }
  static std::string delimiterError(std::uint64_t at) {
    return "has a delimiter at byte " + std::to_string(at) +
           " with a length where it must have "
           "none";
  }
  static std::string hex(std::uint32_t tag) {
    char text[16];
    std::snprintf(text, sizeof text, "%04X,%04X", tag >> 16, tag & 0xffff);
    return text;
  }

  // The public dictionary's VR of `tag`; INVALID for private and unknown tags.
  static gdcm::VR dictionaryVr(std::uint32_t tag) {
    if ((tag >> 16) & 1) return gdcm::VR::INVALID;
    return gdcm::Global::GetInstance()
        .GetDicts()
        .GetPublicDict()
        .GetDictEntry(gdcm::Tag(std::uint16_t(tag >> 16), std::uint16_t(tag)))
        .GetVR();
  }

  std::string file_;
  std::ifstream in_;
  std::uint64_t size_;
  bool explicit_;
};

// Walks the file's elements up to the Pixel Data with ElementWalk (GDCM's own walk that selects
// the Pixel Data reads its fragments: 4.2 GB for the file below), and returns where it stopped:
// at the Pixel Data's tag, or at the file's end when it has none. Refuses a file
// one of whose elements claims more bytes than the file holds: GDCM, reading such a file,
// falls back to other encodings on a failed stream and (built with assertions) aborts the
// program (found by the DICOM fuzz target: a Rows element claiming 53,250 bytes).
std::uint64_t walkToPixelData(const std::string& file, std::string* transferSyntax) {
  std::string uid;
  const std::uint64_t dataSet = checkMetaGroup(file, uid);
  if (transferSyntax) *transferSyntax = uid;
  std::error_code sizeError;
  const std::uint64_t fileSize = fs::file_size(file, sizeError);
  if (sizeError) throw FormatError(file, sizeError.message());
  // Implicit VR little endian (also when the meta group names none), deflated and big endian
  // refused, every other syntax explicit VR little endian.
  if (uid == "1.2.840.10008.1.2.1.99" || uid == "1.2.840.10008.1.2.2")
    throw FormatError(file, "uses transfer syntax " + uid +
                                " (deflated or big endian), which voxwall does not read");
  return ElementWalk(file, fileSize, !uid.empty() && uid != "1.2.840.10008.1.2")
      .list(dataSet, fileSize, 0, false, 0x7fe00010u);
}

// The items of encapsulated (compressed) Pixel Data, walked here before GDCM reads any of them:
// GDCM allocates what each fragment claims, and a 1 KiB file whose fragment claimed 1 GiB cost
// 27 s and 3.2 GB (0xfffffff0: 142 s and 12.7 GB) and was then accepted. Each item must be an
// Item (FFFE,E000) of defined length that ends inside the file, and a Sequence Delimitation Item
// (FFFE,E0DD) must close them.
// Returns where the Pixel Data ends; `fragments` says whether it is a sequence of fragments
// (undefined length). Refuses a file whose pixel data runs past its end (GDCM, walking to it,
// fell back to other encodings on such files and aborted on an assertion).
std::uint64_t pixelDataEnd(const std::string& file, bool& fragments) {
  fragments = false;
  std::string uid;
  std::uint64_t at = walkToPixelData(file, &uid);
  // GDCM's decoders dereference what they expect without checking (a JPEG file whose pixel data
  // was not fragments crashed in gdcm::JPEGCodec::Decode: found by the DICOM fuzz target).
  const bool compressed =
      gdcm::TransferSyntax(gdcm::TransferSyntax::GetTSType(uid.c_str())).IsEncapsulated();
  std::error_code ec;
  const std::uint64_t size = fs::file_size(file, ec);
  std::ifstream in(file, std::ios::binary);
  const auto readAt = [&](std::uint64_t offset, unsigned char* out, std::size_t n) {
    return !ec && offset <= size && n <= size - offset && in.seekg(std::streamoff(offset)) &&
           in.read(reinterpret_cast<char*>(out), std::streamsize(n));
  };
  // The walk stopped at the Pixel Data element's tag. GDCM reads fragments from any Pixel Data
  // of undefined length, whatever the transfer syntax says (the fuzz target found an
  // uncompressed file that way), so the items are walked whenever the length is undefined.
  // Explicit VR: tag, VR, two reserved bytes, the 4-byte length; implicit VR: tag, length.
  unsigned char h[12] = {};
  if (!readAt(at, h, 8) || le16(h) != 0x7fe0 || le16(h + 2) != 0x0010)
    throw FormatError(file, "has no Pixel Data");
  // (GDCM ignores the two reserved bytes after an explicit VR; so does this.)
  const bool explicitVr = isDicomVr(std::string{char(h[4]), char(h[5])});
  if (explicitVr && !readAt(at, h, 12))
    throw FormatError(file, "is cut short inside its Pixel Data element's header");
  const std::uint32_t length = le32(explicitVr ? h + 8 : h + 4);
  at += explicitVr ? 12 : 8;
  if (length != 0xffffffffu) {
    if (at + length > size)
      throw FormatError(file, "is cut short: its pixel data ends at byte " +
                                  std::to_string(at + length) + " but the file has " +
                                  std::to_string(size) + " bytes");
    if (compressed)
      throw FormatError(file, "its transfer syntax " + uid +
                                  " is compressed but its pixel data is not a sequence of "
                                  "fragments");
    return at + length;
  }
  if (!compressed)
    throw FormatError(file, "its pixel data is a sequence of fragments but its transfer syntax " +
                                (uid.empty() ? std::string("(none)") : uid) +
                                " is not a compressed one");
  fragments = true;
  for (int item = 0;; ++item) {
    unsigned char b[8];
    if (!readAt(at, b, 8))
      throw FormatError(file, "its compressed pixel data ends at byte " + std::to_string(size) +
                                  " before its sequence delimiter (cut short)");
    const unsigned group = le16(b), element = le16(b + 2);
    const std::uint32_t length = le32(b + 4);
    // A delimiter's length must be 0: GDCM allocated 3.3 GB for one claiming 0xc4000000 bytes
    // (found by the DICOM fuzz target).
    if (group == 0xfffe && element == 0xe0dd) {
      if (length != 0)
        throw FormatError(file, "the sequence delimiter of its pixel data at byte " +
                                    std::to_string(at) + " has a length (" +
                                    std::to_string(length) + ") where it must have none");
      return at + 8;
    }
    if (group != 0xfffe || element != 0xe000)
      throw FormatError(file,
                        "its compressed pixel data holds something other than an item "
                        "at byte " +
                            std::to_string(at));
    if (length == 0xffffffffu || at + 8 + length > size)
      throw FormatError(
          file, "fragment " + std::to_string(item) + " of its compressed pixel data claims " +
                    std::to_string(length) + " bytes at byte " + std::to_string(at + 8) +
                    ", past the end of the file (" + std::to_string(size) + " bytes)");
    at += 8 + std::uint64_t(length);
  }
}

// A US value of the data set (-1 when missing or not 2 bytes).
int usValue(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  if (!ds.FindDataElement(tag)) return -1;
  const gdcm::ByteValue* bv = ds.GetDataElement(tag).GetByteValue();
  if (!bv || bv->GetLength() != 2) return -1;
  const auto* b = reinterpret_cast<const unsigned char*>(bv->GetPointer());
  return int(b[0]) | int(b[1]) << 8;
}

// GDCM's decoders assert (aborting the program) when a JPEG, JPEG-LS or JPEG 2000 stream
// decodes to fewer bytes than the DICOM header's image (found by the DICOM fuzz target). So the
// stream's own frame header (SOF, SOF55 or SIZ) must give the header's columns, rows, samples
// and bytes per sample.
void checkStreamGeometry(const std::string& file, const std::string& ts, const gdcm::DataSet& ds,
                         const unsigned char* b, std::size_t n) {
  const int rows = usValue(ds, kRows), columns = usValue(ds, kColumns),
            samples = usValue(ds, kSamples), bits = usValue(ds, kBitsAllocated);
  const auto be16 = [&](std::size_t at) { return at + 2 <= n ? int(b[at]) << 8 | b[at + 1] : -1; };
  const auto be32 = [&](std::size_t at) {
    return at + 4 <= n ? std::int64_t(be16(at)) << 16 | be16(at + 2) : std::int64_t(-1);
  };
  std::int64_t width = -1, height = -1;
  int components = -1, precision = -1;
  if (ts.rfind("1.2.840.10008.1.2.4.9", 0) == 0) {
    // JPEG 2000: the SIZ marker segment after SOC, in a bare codestream or a JP2 'jp2c' box.
    std::size_t at = std::string::npos;
    for (std::size_t i = 0; i + 4 <= n; ++i)
      if (b[i] == 0xff && b[i + 1] == 0x4f && b[i + 2] == 0xff && b[i + 3] == 0x51) {
        at = i + 2;
        break;
      }
    if (at != std::string::npos && at + 41 <= n) {
      width = be32(at + 6) - be32(at + 14);
      height = be32(at + 10) - be32(at + 18);
      components = be16(at + 38);
      precision = (b[at + 40] & 0x7f) + 1;
    }
  } else if (ts.rfind("1.2.840.10008.1.2.4.", 0) == 0) {
    // JPEG and JPEG-LS: the marker segments after SOI, each where the previous one ends, up to
    // the first scan (SOS). libjpeg warns of bytes between them, and GDCM asserts on any
    // warning while it reads a JPEG header (found by the DICOM fuzz target).
    std::size_t at = 2;
    bool scan = false;
    while (at + 4 <= n && b[at] == 0xff) {
      const int marker = b[at + 1];
      if (marker == 0xff) {  // a fill byte
        ++at;
        continue;
      }
      if ((marker >= 0xd0 && marker <= 0xd7) || marker == 0x01) {
        at += 2;
        continue;
      }
      const int length = be16(at + 2);
      if (length < 2 || at + 2 + std::size_t(length) > n) break;
      const bool frame = (marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 &&
                          marker != 0xcc) ||
                         marker == 0xf7;
      if (frame && length >= 8 && precision < 0) {
        precision = b[at + 4];
        height = be16(at + 5);
        width = be16(at + 7);
        components = b[at + 9];
      }
      if (marker == 0xda) {
        scan = true;
        break;
      }
      at += 2 + std::size_t(length);
    }
    if (!scan)
      throw FormatError(file,
                        "its JPEG stream's markers do not lead to a scan in its first "
                        "fragment (corrupt)");
  } else {
    return;  // RLE: GDCM decodes it to the header's size
  }
  const int bytesPerSample = precision <= 8 ? 1 : precision <= 16 ? 2 : 4;
  if (width != columns || height != rows || components != samples || precision < 1 ||
      bytesPerSample * 8 != bits)
    throw FormatError(file, "its compressed stream holds " + std::to_string(width) + "x" +
                                std::to_string(height) + " pixels of " +
                                std::to_string(components) + " samples of " +
                                std::to_string(precision) + " bits where its header says " +
                                std::to_string(columns) + "x" + std::to_string(rows) + " of " +
                                std::to_string(samples) + " samples of " + std::to_string(bits) +
                                " bits allocated");
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
  checkStreamGeometry(file, ts, ds, b, n);
}

// Whether an enhanced multi-frame file names its orientation where GDCM looks for it (the
// first item of the shared, then the per-frame functional groups' Plane Orientation, then the
// top level), as six numbers. GDCM's image reader asserts, aborting the program, when it finds
// none (found by the DICOM fuzz target).
bool hasFrameOrientation(const gdcm::DataSet& ds) {
  const auto sixNumbers = [](const gdcm::DataSet& set) {
    const gdcm::Tag iop(0x0020, 0x0037);
    if (!set.FindDataElement(iop)) return false;
    const gdcm::ByteValue* bv = set.GetDataElement(iop).GetByteValue();
    return bv && numbersOf(std::string(bv->GetPointer(), bv->GetLength())).size() == 6;
  };
  for (const gdcm::Tag& groups : {gdcm::Tag(0x5200, 0x9229), gdcm::Tag(0x5200, 0x9230)}) {
    if (!ds.FindDataElement(groups)) continue;
    const auto items = ds.GetDataElement(groups).GetValueAsSQ();
    if (!items || items->GetNumberOfItems() == 0) continue;
    const gdcm::DataSet& first = items->GetItem(1).GetNestedDataSet();
    const gdcm::Tag plane(0x0020, 0x9116);
    if (!first.FindDataElement(plane)) continue;
    const auto planes = first.GetDataElement(plane).GetValueAsSQ();
    if (planes && planes->GetNumberOfItems() > 0 &&
        sixNumbers(planes->GetItem(1).GetNestedDataSet()))
      return true;
  }
  return sixNumbers(ds);
}

// An image with functional groups (enhanced, usually multi-frame) must name its orientation
// where GDCM looks for it; call after pixelDataEnd() checked the file.
void checkFunctionalGroups(const std::string& file) {
  gdcm::Reader head;
  head.SetFileName(file.c_str());
  if (!head.ReadUpToTag(kPixelData, {kPixelData}))
    throw FormatError(file, "GDCM cannot read it as DICOM (corrupt header)");
  const gdcm::DataSet& ds = head.GetFile().GetDataSet();
  if ((ds.FindDataElement(gdcm::Tag(0x5200, 0x9229)) ||
       ds.FindDataElement(gdcm::Tag(0x5200, 0x9230))) &&
      !hasFrameOrientation(ds))
    throw FormatError(file,
                      "has functional groups but no Image Orientation (Patient) of six numbers "
                      "in them");
}

Decoded decode(const std::string& file, std::vector<std::byte>& buffer, std::size_t offset,
               std::size_t expectBytes) {
  bool encapsulated = false;
  const std::size_t end = pixelDataEnd(file, encapsulated);
  checkFunctionalGroups(file);
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
    if (s.samples != 1)
      throw FormatError(s.file, "is a colour image (" + std::to_string(s.samples) +
                                    " samples per pixel); voxwall reads greyscale DICOM");
  for (const SliceHeader& s : slices)
    if (s.frames > 1) {
      if (slices.size() > 1)
        throw FormatError(path, name + " holds " + std::to_string(slices.size()) +
                                    " files of which " + s.file +
                                    " has several frames; read one multi-frame file at a time");
      return readMultiFrame(s);
    }

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
