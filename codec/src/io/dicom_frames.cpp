#include "dicom_frames.hpp"

#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>
#include <voxwall/core/errors.hpp>

#include "dicom_checks.hpp"

namespace voxwall::codec::dicom {
namespace {

const gdcm::Tag kSharedGroups(0x5200, 0x9229), kPerFrameGroups(0x5200, 0x9230);
const gdcm::Tag kPlanePosition(0x0020, 0x9113), kPosition(0x0020, 0x0032);
const gdcm::Tag kPlaneOrientation(0x0020, 0x9116), kOrientation(0x0020, 0x0037);
const gdcm::Tag kPixelMeasures(0x0028, 0x9110), kPixelSpacing(0x0028, 0x0030),
    kSliceThickness(0x0018, 0x0050);
const gdcm::Tag kValueTransformation(0x0028, 0x9145), kIntercept(0x0028, 0x1052),
    kSlope(0x0028, 0x1053);
const gdcm::Tag kFrameContent(0x0020, 0x9111), kDimensionValues(0x0020, 0x9157),
    kStackId(0x0020, 0x9056), kInStackPosition(0x0020, 0x9057), kTemporalIndex(0x0020, 0x9128);
const gdcm::Tag kDimensionIndex(0x0020, 0x9222), kDimensionPointer(0x0020, 0x9165);
const gdcm::Tag kMrFrameType(0x0018, 0x9226), kCtFrameType(0x0018, 0x9329),
    kFrameType(0x0008, 0x9007);
const gdcm::Tag kMrEcho(0x0018, 0x9114), kEchoTime(0x0018, 0x9082);
const gdcm::Tag kDiffusion(0x0018, 0x9117), kBValue(0x0018, 0x9087);
const gdcm::Tag kCardiacSync(0x0018, 0x9118), kTriggerTime(0x0020, 0x9153);

using Items = gdcm::SmartPointer<gdcm::SequenceOfItems>;

Items itemsOf(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  if (!ds.FindDataElement(tag)) return nullptr;
  const gdcm::DataElement& de = ds.GetDataElement(tag);
  if (de.IsEmpty()) return nullptr;
  return de.GetValueAsSQ();
}

// The first item of a sequence in `ds`, or nullptr.
const gdcm::DataSet* firstItem(const gdcm::DataSet& ds, const gdcm::Tag& sequence) {
  const Items items = itemsOf(ds, sequence);
  if (!items || items->GetNumberOfItems() == 0) return nullptr;
  return &items->GetItem(1).GetNestedDataSet();
}

std::optional<std::string> bytesOf(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  if (!ds.FindDataElement(tag)) return std::nullopt;
  const gdcm::ByteValue* bv = ds.GetDataElement(tag).GetByteValue();
  if (!bv) return std::nullopt;
  return std::string(bv->GetPointer(), bv->GetLength());
}

// The text value of `attribute` in the first item of `sequence`: in the frame's own group, else
// the shared group (either may be null).
std::optional<std::string> groupText(const gdcm::DataSet* frame, const gdcm::DataSet* shared,
                                     const gdcm::Tag& sequence, const gdcm::Tag& attribute) {
  for (const gdcm::DataSet* group : {frame, shared}) {
    if (!group) continue;
    const gdcm::DataSet* item = firstItem(*group, sequence);
    if (!item) continue;
    if (auto bytes = bytesOf(*item, attribute)) return trimmed(bytes->c_str());
  }
  return std::nullopt;
}

// A binary double (FD: echo time, b-value, trigger time) in the first item of `sequence` of the
// frame's own group, as text; also read as text where a writer put DS there.
std::optional<std::string> frameDouble(const gdcm::DataSet* frame, const gdcm::Tag& sequence,
                                       const gdcm::Tag& attribute) {
  if (!frame) return std::nullopt;
  const gdcm::DataSet* item = firstItem(*frame, sequence);
  if (!item) return std::nullopt;
  const auto bytes = bytesOf(*item, attribute);
  if (!bytes) return std::nullopt;
  const gdcm::VR vr = item->GetDataElement(attribute).GetVR();
  if (bytes->size() == 8 && vr != gdcm::VR::DS) {
    double v;
    std::memcpy(&v, bytes->data(), 8);
    char text[32];
    std::snprintf(text, sizeof text, "%g", v);
    return std::string(text);
  }
  return trimmed(bytes->c_str());
}

// Little-endian unsigned 32-bit values (UL), or attribute tags (AT: group then element, each a
// little-endian 16-bit value) as group << 16 | element. Big-endian files are refused before.
std::vector<std::uint32_t> ulValues(const std::string& bytes) {
  std::vector<std::uint32_t> out;
  for (std::size_t i = 0; i + 4 <= bytes.size(); i += 4) {
    std::uint32_t v;
    std::memcpy(&v, bytes.data() + i, 4);
    out.push_back(v);
  }
  return out;
}
std::vector<std::uint32_t> atValues(const std::string& bytes) {
  std::vector<std::uint32_t> out;
  for (std::size_t i = 0; i + 4 <= bytes.size(); i += 4) {
    std::uint16_t g, e;
    std::memcpy(&g, bytes.data() + i, 2);
    std::memcpy(&e, bytes.data() + i + 2, 2);
    out.push_back(std::uint32_t(g) << 16 | e);
  }
  return out;
}

std::uint32_t tagKey(const gdcm::Tag& t) {
  return std::uint32_t(t.GetGroup()) << 16 | t.GetElement();
}

}  // namespace

std::vector<FrameGeometry> enhancedFrames(const std::string& file, int frames) {
  gdcm::Reader reader;
  reader.SetFileName(file.c_str());
  const gdcm::Tag pixelData(0x7fe0, 0x0010);
  if (!reader.ReadUpToTag(pixelData, {pixelData}))
    throw FormatError(file, "GDCM cannot read it as DICOM (corrupt header)");
  const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
  const Items perFrame = itemsOf(ds, kPerFrameGroups);
  if (!perFrame) return {};
  if (perFrame->GetNumberOfItems() != std::size_t(frames))
    throw FormatError(file, "has " + std::to_string(perFrame->GetNumberOfItems()) +
                                " items in its Per-frame Functional Groups Sequence for " +
                                std::to_string(frames) + " frames");
  const gdcm::DataSet* shared = firstItem(ds, kSharedGroups);
  // Which dimension index values place a frame in its stack (left out of its image's key).
  std::vector<std::uint32_t> pointers;
  if (const Items dims = itemsOf(ds, kDimensionIndex))
    for (std::size_t i = 1; i <= dims->GetNumberOfItems(); ++i) {
      const auto at = bytesOf(dims->GetItem(i).GetNestedDataSet(), kDimensionPointer);
      const auto values = at ? atValues(*at) : std::vector<std::uint32_t>{};
      pointers.push_back(values.empty() ? 0 : values.front());
    }
  std::vector<FrameGeometry> out(static_cast<std::size_t>(frames));
  for (int f = 0; f < frames; ++f) {
    const gdcm::DataSet* own = &perFrame->GetItem(std::size_t(f) + 1).GetNestedDataSet();
    FrameGeometry& g = out[std::size_t(f)];
    auto numbers = [&](const gdcm::Tag& seq, const gdcm::Tag& attr) {
      const auto text = groupText(own, shared, seq, attr);
      return text ? numbersOf(*text) : std::vector<double>{};
    };
    g.position = numbers(kPlanePosition, kPosition);
    if (const auto text = groupText(own, shared, kPlanePosition, kPosition))
      g.positionDecimals = decimalsOf(*text);
    g.orientation = numbers(kPlaneOrientation, kOrientation);
    g.pixelSpacing = numbers(kPixelMeasures, kPixelSpacing);
    const auto thickness = numbers(kPixelMeasures, kSliceThickness);
    if (thickness.size() == 1) g.sliceThickness = thickness[0];
    const auto slope = numbers(kValueTransformation, kSlope);
    const auto intercept = numbers(kValueTransformation, kIntercept);
    if (slope.size() == 1 && intercept.size() == 1) {
      if (slope[0] == 0)
        throw FormatError(file, "frame " + std::to_string(f + 1) + " has Rescale Slope 0");
      g.rescaled = true, g.slope = slope[0], g.intercept = intercept[0];
    }
    auto part = [&g](const std::string& name, const std::string& value) {
      if (value.empty()) return;
      g.image += name + "=" + value + ";";
      g.label += (g.label.empty() ? "" : ", ") + name + " " + printable(value);
    };
    if (const gdcm::DataSet* content = firstItem(*own, kFrameContent)) {
      // Without the Dimension Index Sequence nothing says which index is the position.
      const auto values = bytesOf(*content, kDimensionValues);
      const auto index = values ? ulValues(*values) : std::vector<std::uint32_t>{};
      if (!pointers.empty() && index.size() == pointers.size()) {
        std::string others;
        for (std::size_t i = 0; i < index.size(); ++i) {
          const std::uint32_t pointer = pointers[i];
          // Time is not what tells images apart: it orders an image's frames into time steps.
          if (pointer == tagKey(kInStackPosition) || pointer == tagKey(kPosition) ||
              pointer == tagKey(kTemporalIndex) || pointer == tagKey(kTriggerTime))
            continue;
          others += (others.empty() ? "" : ",") + std::to_string(index[i]);
        }
        part("dimension index", others);
      }
      if (const auto stack = bytesOf(*content, kStackId)) part("stack", trimmed(stack->c_str()));
      if (const auto time = bytesOf(*content, kTemporalIndex)) {
        const auto t = ulValues(*time);
        if (!t.empty()) g.temporalIndex = double(t.front());
      }
    }
    for (const gdcm::Tag& seq : {kMrFrameType, kCtFrameType})
      if (const auto type = groupText(own, nullptr, seq, kFrameType)) part("frame type", *type);
    if (const auto echo = frameDouble(own, kMrEcho, kEchoTime)) part("echo time", *echo);
    if (const auto b = frameDouble(own, kDiffusion, kBValue)) part("b-value", *b);
    if (const auto trigger = frameDouble(own, kCardiacSync, kTriggerTime)) {
      const auto ms = numbersOf(*trigger);
      if (ms.size() == 1) g.triggerTime = ms[0];
    }
  }
  return out;
}

}  // namespace voxwall::codec::dicom
