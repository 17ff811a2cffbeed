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
#include "dicom_images.hpp"
#include "dicom_pixels.hpp"
#include "dicom_slices.hpp"

namespace voxwall::codec {
namespace {

namespace fs = std::filesystem;
using dicom::checkCompressedStart;
using dicom::checkElements;
using dicom::checkImageHeader;
using dicom::Contents;
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
// What tells a single-frame file's image from the series' others, in the order its label says
// them, and what orders repeats at one position in time (SliceHeader::time's order).
const std::pair<gdcm::Tag, const char*> kImageTags[] = {
    {gdcm::Tag(0x0008, 0x0008), "image type"},
    {gdcm::Tag(0x0018, 0x0086), "echo"},
    {gdcm::Tag(0x0018, 0x0081), "echo time"},
    {gdcm::Tag(0x0018, 0x9087), "b-value"},
    {gdcm::Tag(0x0018, 0x9089), "gradient direction"},
    {gdcm::Tag(0x0018, 0x0024), "sequence"}};  // Siemens names a b-value in it (ep_b1000#1)
const gdcm::Tag kTemporalPosition(0x0020, 0x0100), kTriggerTime(0x0018, 0x1060),
    kAcquisitionTime(0x0008, 0x0032), kContentTime(0x0008, 0x0033), kInstance(0x0020, 0x0013);

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

// One number, or NaN.
double numberOf(const std::string& text) {
  const auto v = numbersOf(text);
  return v.size() == 1 ? v[0] : SliceHeader::kNone;
}

// A single-frame file's image key and label, and its time keys, from its scanned `value`s.
template <class Value>
void setImageAndTime(SliceHeader& h, Value&& value) {
  for (const auto& [tag, name] : kImageTags) {
    const std::string text = value(tag);
    if (text.empty()) continue;
    h.image += std::string(name) + "=" + text + ";";
    h.label += (h.label.empty() ? "" : ", ") + std::string(name) + " " + dicom::printable(text);
  }
  h.time[SliceHeader::kTemporalPosition] = numberOf(value(kTemporalPosition));
  h.time[SliceHeader::kTriggerTime] = numberOf(value(kTriggerTime));
  h.time[SliceHeader::kAcquisitionTime] = dicom::secondsOfDay(value(kAcquisitionTime));
  h.time[SliceHeader::kContentTime] = dicom::secondsOfDay(value(kContentTime));
  h.time[SliceHeader::kInstance] = numberOf(value(kInstance));
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
                             kOrientation, kFrames, kSamples, kBitsAllocated, kTemporalPosition,
                             kTriggerTime, kAcquisitionTime, kContentTime, kInstance})
    scanner.AddTag(t);
  for (const auto& [tag, name] : kImageTags) scanner.AddTag(tag);
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
    setImageAndTime(h, value);
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
    v.orientation = dicom::orientationOf(first.orientation.data(), first.position.data());
  }
}

// The frames of an enhanced file as slices, each with its own geometry, rescale, image key and
// time; none for a multi-frame file without functional groups. Frames at one position that
// nothing else orders in time are ordered by the file's Instance Number, then their own order.
std::vector<SliceHeader> framesOf(const SliceHeader& h) {
  const std::vector<dicom::FrameGeometry> frames = dicom::enhancedFrames(h.file, h.frames);
  std::vector<SliceHeader> out;
  const double instance =
      std::isfinite(h.time[SliceHeader::kInstance]) ? h.time[SliceHeader::kInstance] : 0;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const dicom::FrameGeometry& g = frames[f];
    SliceHeader s = h;
    s.source = h.file;
    s.file = h.file + " (frame " + std::to_string(f + 1) + ")";
    s.frame = int(f);
    s.position = g.position, s.orientation = g.orientation;
    s.decimals = g.positionDecimals;
    // The frame's own keys after the file's (top-level echo time, trigger time, ...).
    s.image = h.image + g.image;
    s.label = h.label.empty() || g.label.empty() ? h.label + g.label : h.label + ", " + g.label;
    if (std::isfinite(g.temporalIndex)) s.time[SliceHeader::kTemporalPosition] = g.temporalIndex;
    if (std::isfinite(g.triggerTime)) s.time[SliceHeader::kTriggerTime] = g.triggerTime;
    s.time[SliceHeader::kInstance] = instance * 1e6 + double(f);
    s.pixelSpacing = g.pixelSpacing, s.sliceThickness = g.sliceThickness;
    s.rescaled = g.rescaled, s.slope = g.slope, s.intercept = g.intercept;
    out.push_back(std::move(s));
  }
  return out;
}

// What a series holds: its images, each in time steps, from its single-frame files (ordered by
// Instance Number, so that images are numbered as the scanner numbered their first slices) or
// the frames of its enhanced files (in the files' then the frames' order); or one multi-frame
// file without functional groups, read as it stores its frames.
Contents contentsOf(const Series& series, const std::string& path) {
  Contents c;
  c.name = series.info.uid.empty() ? path : "series " + series.info.uid;
  std::vector<SliceHeader> slices = series.slices;
  for (const SliceHeader& s : slices)
    if (s.samples != 1)
      throw FormatError(s.file, "is a colour image (" + std::to_string(s.samples) +
                                    " samples per pixel); voxwall reads greyscale DICOM");
  const auto byInstance = [](const SliceHeader& a, const SliceHeader& b) {
    const double inf = std::numeric_limits<double>::infinity();
    const double x =
        std::isfinite(a.time[SliceHeader::kInstance]) ? a.time[SliceHeader::kInstance] : inf;
    const double y =
        std::isfinite(b.time[SliceHeader::kInstance]) ? b.time[SliceHeader::kInstance] : inf;
    return x < y || (x == y && a.file < b.file);
  };
  std::stable_sort(slices.begin(), slices.end(), byInstance);
  c.where = slices.size() == 1 ? slices.front().file : path;
  c.unit = "files";
  // Enhanced files hold their geometry in functional groups: multi-frame files, and single
  // frames without a top-level Image Position (GDCM writes an MR with a rescale that way).
  const bool multi =
      std::any_of(slices.begin(), slices.end(), [](const SliceHeader& s) { return s.frames > 1; });
  const bool placeless = std::any_of(slices.begin(), slices.end(),
                                     [](const SliceHeader& s) { return s.position.size() != 3; });
  if (multi || placeless) {
    std::vector<SliceHeader> frames;
    for (const SliceHeader& h : slices) {
      const std::vector<SliceHeader> of = framesOf(h);
      if (!of.empty()) {
        frames.insert(frames.end(), of.begin(), of.end());
        continue;
      }
      if (!multi) break;  // single frames without functional groups: read as slices
      if (slices.size() == 1) {
        c.plainMultiFrame = h;
        return c;
      }
      throw FormatError(path, c.name + " holds " + std::to_string(slices.size()) +
                                  " files of which " + h.file +
                                  (h.frames > 1 ? " has several frames without functional groups"
                                                : " is a single frame among multi-frame files") +
                                  "; read one multi-frame file at a time");
    }
    if (frames.size() >= slices.size()) {
      slices = std::move(frames);
      c.unit = "frames";
    }
  }
  c.images = dicom::splitSeries(slices, path, c.name);
  return c;
}

// One time step of one image: its slices placed, decoded and rescaled into one volume.
Volume readSlices(std::vector<SliceHeader> slices, const std::string& path, const std::string& name,
                  const DicomOptions& options) {
  const SliceAxes axes = placeSlices(slices, path, name, options);
  const SliceHeader& first = slices.front();
  const glm::ivec3 dims(first.columns, first.rows, int(slices.size()));
  checkDims(dims, path);
  std::vector<std::byte> stored;
  const std::vector<dicom::Decoded> decoded = dicom::decodeSlices(slices, dims, stored);
  glm::dvec3 spacing = decoded.front().spacing;
  const bool frames = first.frame >= 0;
  if (frames) {
    for (const SliceHeader& s : slices)
      if (s.pixelSpacing != first.pixelSpacing)
        throw FormatError(s.source, "frame " + std::to_string(s.frame + 1) +
                                        " has another Pixel Spacing than frame " +
                                        std::to_string(first.frame + 1) + " of " + name);
    // DICOM's Pixel Spacing is rows apart, then columns apart: y, then x.
    if (first.pixelSpacing.size() == 2)
      spacing.x = first.pixelSpacing[1], spacing.y = first.pixelSpacing[0];
  }
  for (int i = 0; i < 2; ++i)
    if (!(spacing[i] > 0) || !std::isfinite(spacing[i]))
      throw FormatError(frames ? first.source : first.file,
                        "has no usable Pixel Spacing (" + fixed(spacing[i], 4) + ")");
  if (slices.size() > 1)
    spacing.z = fittedGap(slices);
  else if (frames)
    spacing.z = first.sliceThickness > 0 ? first.sliceThickness : 1;
  else if (!(spacing.z > 0) || !std::isfinite(spacing.z))
    spacing.z = 1;
  Volume v = dicom::rescaled(std::move(stored), decoded.front().stored, dims, spacing, decoded);
  placeInPatient(v, slices, axes, path, name, options);
  return v;
}

}  // namespace

struct DicomInput::Impl {
  std::string path;
  DicomOptions options;
  Contents contents;
  const dicom::SeriesImage* image = nullptr;  // the picked one; null for a plain multi-frame file
  std::string name;                           // the image in errors
};

DicomInput::DicomInput(const std::string& path, const DicomOptions& options) {
  const auto made = std::make_shared<Impl>();
  impl_ = made;
  Impl& in = *made;
  in.path = path, in.options = options;
  const auto all = scanSeries(path);
  in.contents = contentsOf(pickSeries(all, path, options), path);
  const Contents& c = in.contents;
  in.name = c.name;
  if (c.plainMultiFrame) {
    if (options.image > 1)
      throw FormatError(c.where, "holds 1 image; --dicom-image " + std::to_string(options.image) +
                                     " is not one of them");
    return;
  }
  in.image = &dicom::pickImage(c.images, options, c.where, c.unit);
  if (c.images.size() > 1) in.name += " image " + std::to_string(options.image);
}

int DicomInput::steps() const { return impl_->image ? int(impl_->image->steps.size()) : 1; }

std::string DicomInput::describeSteps() const {
  const dicom::SeriesImage* image = impl_->image;
  if (!image || image->steps.size() < 2) return "";
  return std::to_string(image->steps.size()) + " time steps of " +
         std::to_string(image->steps.front().size()) + " slices, ordered by " + image->orderedBy;
}

Volume DicomInput::read(int step) const {
  const Impl& in = *impl_;
  if (!in.image) return dicom::readMultiFrame(*in.contents.plainMultiFrame);
  if (step < 0 || step >= steps())
    throw std::out_of_range("DICOM step " + std::to_string(step) + " of " +
                            std::to_string(steps()));
  const std::string name = steps() > 1 ? in.name + " step " + std::to_string(step) : in.name;
  return readSlices(in.image->steps[std::size_t(step)], in.path, name, in.options);
}

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

std::vector<DicomImageInfo> listDicomImages(const std::string& path, const DicomOptions& options) {
  const auto all = scanSeries(path);
  const Contents c = contentsOf(pickSeries(all, path, options), path);
  if (c.plainMultiFrame) return {DicomImageInfo{"", c.plainMultiFrame->frames, 1, ""}};
  std::vector<DicomImageInfo> out;
  for (const dicom::SeriesImage& image : c.images)
    out.push_back(
        {image.label, int(image.steps.front().size()), int(image.steps.size()), image.orderedBy});
  return out;
}

Volume readDicom(const std::string& path, const DicomOptions& options) {
  const DicomInput input(path, options);
  if (input.steps() > 1)
    throw FormatError(path, "holds " + input.describeSteps() +
                                ": a time series (`voxwall compress` makes one .vwz of its steps)");
  return input.read(0);
}

}  // namespace voxwall::codec
