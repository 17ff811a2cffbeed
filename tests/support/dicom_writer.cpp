#include "support/dicom_writer.hpp"

#include <gdcmAttribute.h>
#include <gdcmImageChangeTransferSyntax.h>
#include <gdcmImageWriter.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmTrace.h>
#include <gdcmWriter.h>

#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <stdexcept>
#include <utility>

namespace voxwall::test {
namespace {

gdcm::TransferSyntax syntaxOf(DicomSyntax s) {
  switch (s) {
    case DicomSyntax::ExplicitLittle:
      return gdcm::TransferSyntax::ExplicitVRLittleEndian;
    case DicomSyntax::ImplicitLittle:
      return gdcm::TransferSyntax::ImplicitVRLittleEndian;
    case DicomSyntax::Rle:
      return gdcm::TransferSyntax::RLELossless;
    case DicomSyntax::JpegLs:
      return gdcm::TransferSyntax::JPEGLSLossless;
    case DicomSyntax::JpegLossless:
      return gdcm::TransferSyntax::JPEGLosslessProcess14_1;
  }
  throw std::logic_error("unknown transfer syntax");
}

// Image Position (Patient) as a scanner that rounds writes it: GDCM's image writer sets it from
// the double, so the file is read back and the element replaced.
void rewritePosition(const std::string& path, const glm::dvec3& p, int decimals) {
  std::string value;
  for (int i = 0; i < 3; ++i) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, p[i]);
    std::string v = buf;
    if (v.find('.') != std::string::npos) {
      while (v.back() == '0') v.pop_back();
      if (v.back() == '.') v.pop_back();
    }
    if (v == "-0") v = "0";
    if (i) value += '\\';
    value += v;
  }
  if (value.size() % 2) value += ' ';
  gdcm::Reader reader;
  reader.SetFileName(path.c_str());
  if (!reader.Read()) throw std::runtime_error("GDCM cannot read back " + path);
  gdcm::DataElement ipp(gdcm::Tag(0x0020, 0x0032));
  ipp.SetVR(gdcm::VR::DS);
  ipp.SetByteValue(value.data(), std::uint32_t(value.size()));
  reader.GetFile().GetDataSet().Replace(ipp);
  gdcm::Writer writer;
  writer.SetFile(reader.GetFile());
  writer.SetFileName(path.c_str());
  if (!writer.Write()) throw std::runtime_error("GDCM cannot rewrite " + path);
}

// A text value (padded to an even length) or a binary one.
void putValue(gdcm::DataSet& ds, const gdcm::Tag& tag, gdcm::VR vr, std::string bytes) {
  if (bytes.size() % 2) bytes += vr == gdcm::VR::UI ? '\0' : ' ';
  gdcm::DataElement de(tag);
  de.SetVR(vr);
  de.SetByteValue(bytes.data(), std::uint32_t(bytes.size()));
  ds.Replace(de);
}

std::string decimal(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

void putRepeatKeys(gdcm::DataSet& ds, const DicomSlice& s) {
  if (!s.imageType.empty()) putValue(ds, gdcm::Tag(0x0008, 0x0008), gdcm::VR::CS, s.imageType);
  if (!s.acquisitionTime.empty())
    putValue(ds, gdcm::Tag(0x0008, 0x0032), gdcm::VR::TM, s.acquisitionTime);
  if (s.echoTime >= 0) putValue(ds, gdcm::Tag(0x0018, 0x0081), gdcm::VR::DS, decimal(s.echoTime));
  if (s.echoNumber > 0)
    putValue(ds, gdcm::Tag(0x0018, 0x0086), gdcm::VR::IS, std::to_string(s.echoNumber));
  if (s.triggerTime >= 0)
    putValue(ds, gdcm::Tag(0x0018, 0x1060), gdcm::VR::DS, decimal(s.triggerTime));
  if (s.bValue >= 0) {
    std::string bytes(8, '\0');
    std::memcpy(bytes.data(), &s.bValue, 8);
    putValue(ds, gdcm::Tag(0x0018, 0x9087), gdcm::VR::FD, bytes);
  }
  if (s.temporalPosition > 0)
    putValue(ds, gdcm::Tag(0x0020, 0x0100), gdcm::VR::IS, std::to_string(s.temporalPosition));
}

}  // namespace

void writeDicom(const std::string& path, const DicomSlice& s) {
  if (s.pixels.size() != std::size_t(s.columns) * std::size_t(s.rows) * std::size_t(s.frames))
    throw std::invalid_argument("writeDicom: pixels do not match columns x rows x frames");
  gdcm::Trace::SetWarning(false);
  gdcm::ImageWriter writer;
  gdcm::Image& image = writer.GetImage();
  const bool multi = s.frames > 1;
  image.SetNumberOfDimensions(multi ? 3 : 2);
  const unsigned dims[3] = {unsigned(s.columns), unsigned(s.rows), unsigned(s.frames)};
  image.SetDimensions(dims);
  image.SetPixelFormat(
      gdcm::PixelFormat(s.isUnsigned ? gdcm::PixelFormat::UINT16 : gdcm::PixelFormat::INT16));
  image.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::MONOCHROME2);
  image.SetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
  image.SetSlope(s.slope);
  image.SetIntercept(s.intercept);
  const double spacing[3] = {s.pixelSpacing.x, s.pixelSpacing.y, s.sliceSpacing};
  image.SetSpacing(spacing);
  for (unsigned i = 0; i < 3; ++i) image.SetOrigin(i, s.position[int(i)]);
  image.SetDirectionCosines(s.orientation.data());
  gdcm::DataElement pixels(gdcm::Tag(0x7fe0, 0x0010));
  pixels.SetByteValue(reinterpret_cast<const char*>(s.pixels.data()),
                      std::uint32_t(s.pixels.size() * 2));
  image.SetDataElement(pixels);

  gdcm::DataSet& ds = writer.GetFile().GetDataSet();
  auto put = [&ds](auto attribute) { ds.Replace(attribute.GetAsDataElement()); };
  // GDCM picks the SOP class from the modality: CT Image Storage, or for frames (which CT Image
  // Storage cannot hold) Multi-frame Grayscale Word Secondary Capture, which needs unsigned pixels.
  put(gdcm::Attribute<0x0008, 0x0060>{multi ? "OT" : s.modality.c_str()});
  put(gdcm::Attribute<0x0008, 0x103e>{s.description.c_str()});
  put(gdcm::Attribute<0x0020, 0x000e>{s.seriesUid.c_str()});
  put(gdcm::Attribute<0x0020, 0x0013>{s.instance});
  putRepeatKeys(ds, s);
  writer.GetFile().GetHeader().SetDataSetTransferSyntax(
      gdcm::TransferSyntax::ExplicitVRLittleEndian);
  gdcm::ImageChangeTransferSyntax change;
  if (s.syntax != DicomSyntax::ExplicitLittle) {
    change.SetTransferSyntax(syntaxOf(s.syntax));
    change.SetInput(image);
    if (!change.Change()) throw std::runtime_error("GDCM cannot change the transfer syntax");
    writer.SetImage(change.GetOutput());
  }
  writer.SetFileName(path.c_str());
  if (!writer.Write()) throw std::runtime_error("GDCM cannot write " + path);
  if (s.positionDecimals >= 0) rewritePosition(path, s.position, s.positionDecimals);
}

}  // namespace voxwall::test

namespace voxwall::test {
namespace {

gdcm::DataElement sequenceOf(const gdcm::Tag& tag, const std::vector<gdcm::DataSet>& items) {
  gdcm::SmartPointer<gdcm::SequenceOfItems> sq = new gdcm::SequenceOfItems;
  sq->SetLengthToUndefined();
  for (const gdcm::DataSet& nested : items) {
    gdcm::Item item;
    item.SetVLToUndefined();
    item.SetNestedDataSet(nested);
    sq->AddItem(item);
  }
  gdcm::DataElement de(tag);
  de.SetVR(gdcm::VR::SQ);
  de.SetValue(*sq);
  de.SetVLToUndefined();
  return de;
}

// A one-item sequence holding `element`.
gdcm::DataElement wrap(const gdcm::Tag& tag, const gdcm::DataElement& element) {
  gdcm::DataSet item;
  item.Insert(element);
  return sequenceOf(tag, {item});
}

// A DS or CS value as the writer gives it.
gdcm::DataElement text(const gdcm::Tag& tag, gdcm::VR vr, std::string value) {
  if (value.size() % 2) value += ' ';
  gdcm::DataElement de(tag);
  de.SetVR(vr);
  de.SetByteValue(value.data(), std::uint32_t(value.size()));
  return de;
}

std::string numbers(std::initializer_list<double> values) {
  std::string out;
  char buf[32];
  for (const double v : values) {
    std::snprintf(buf, sizeof buf, "%.6g", v);
    if (!out.empty()) out += '\\';
    out += buf;
  }
  return out;
}

gdcm::DataElement binary(const gdcm::Tag& tag, gdcm::VR vr, const void* data, std::size_t bytes) {
  gdcm::DataElement de(tag);
  de.SetVR(vr);
  de.SetByteValue(static_cast<const char*>(data), std::uint32_t(bytes));
  return de;
}

}  // namespace

void writeEnhancedDicom(const std::string& path, const EnhancedImage& e) {
  gdcm::Trace::SetWarning(false);
  const bool ct = e.modality == "CT";
  gdcm::Writer writer;
  gdcm::DataSet& ds = writer.GetFile().GetDataSet();
  const std::string sopClass =
      ct ? "1.2.840.10008.5.1.4.1.1.2.1" : "1.2.840.10008.5.1.4.1.1.4.1";  // Enhanced CT / MR
  ds.Insert(text(gdcm::Tag(0x0008, 0x0016), gdcm::VR::UI, sopClass));
  ds.Insert(text(gdcm::Tag(0x0008, 0x0018), gdcm::VR::UI,
                 e.seriesUid + "." + std::to_string(e.instance)));
  ds.Insert(text(gdcm::Tag(0x0008, 0x0060), gdcm::VR::CS, e.modality));
  ds.Insert(text(gdcm::Tag(0x0020, 0x000d), gdcm::VR::UI, e.seriesUid + ".0"));
  ds.Insert(text(gdcm::Tag(0x0020, 0x000e), gdcm::VR::UI, e.seriesUid));
  ds.Insert(text(gdcm::Tag(0x0020, 0x0013), gdcm::VR::IS, std::to_string(e.instance)));
  const std::uint16_t one = 1, rows = std::uint16_t(e.rows), columns = std::uint16_t(e.columns),
                      sixteen = 16, fifteen = 15;
  ds.Insert(binary(gdcm::Tag(0x0028, 0x0002), gdcm::VR::US, &one, 2));
  ds.Insert(text(gdcm::Tag(0x0028, 0x0004), gdcm::VR::CS, "MONOCHROME2"));
  ds.Insert(text(gdcm::Tag(0x0028, 0x0008), gdcm::VR::IS, std::to_string(e.frames.size())));
  ds.Insert(binary(gdcm::Tag(0x0028, 0x0010), gdcm::VR::US, &rows, 2));
  ds.Insert(binary(gdcm::Tag(0x0028, 0x0011), gdcm::VR::US, &columns, 2));
  // What a reader of the top-level attributes alone would take: 1 mm pixels.
  ds.Insert(text(gdcm::Tag(0x0028, 0x0030), gdcm::VR::DS, "1\\1"));
  ds.Insert(binary(gdcm::Tag(0x0028, 0x0100), gdcm::VR::US, &sixteen, 2));
  ds.Insert(binary(gdcm::Tag(0x0028, 0x0101), gdcm::VR::US, &sixteen, 2));
  ds.Insert(binary(gdcm::Tag(0x0028, 0x0102), gdcm::VR::US, &fifteen, 2));
  ds.Insert(binary(gdcm::Tag(0x0028, 0x0103), gdcm::VR::US, &one, 2));  // signed

  // Shared: orientation and pixel measures.
  gdcm::DataSet shared;
  const auto& o = e.orientation;
  shared.Insert(
      wrap(gdcm::Tag(0x0020, 0x9116), text(gdcm::Tag(0x0020, 0x0037), gdcm::VR::DS,
                                           numbers({o[0], o[1], o[2], o[3], o[4], o[5]}))));
  gdcm::DataSet measures;
  measures.Insert(
      text(gdcm::Tag(0x0028, 0x0030), gdcm::VR::DS, numbers({e.pixelSpacing.y, e.pixelSpacing.x})));
  measures.Insert(text(gdcm::Tag(0x0018, 0x0050), gdcm::VR::DS, numbers({e.sliceThickness})));
  shared.Insert(sequenceOf(gdcm::Tag(0x0028, 0x9110), {measures}));
  ds.Insert(sequenceOf(gdcm::Tag(0x5200, 0x9229), {shared}));

  // Per frame: content (dimension index values, stack), position, rescale, frame type.
  std::vector<gdcm::DataSet> perFrame;
  std::vector<std::int16_t> pixels;
  for (const EnhancedFrame& f : e.frames) {
    if (f.pixels.size() != std::size_t(e.columns) * std::size_t(e.rows))
      throw std::invalid_argument("writeEnhancedDicom: a frame's pixels are not columns x rows");
    pixels.insert(pixels.end(), f.pixels.begin(), f.pixels.end());
    gdcm::DataSet frame;
    gdcm::DataSet content;
    const std::uint32_t index[2] = {f.imageIndex, f.stackPosition};
    content.Insert(binary(gdcm::Tag(0x0020, 0x9157), gdcm::VR::UL, index, sizeof index));
    content.Insert(text(gdcm::Tag(0x0020, 0x9056), gdcm::VR::SH, f.stackId));
    content.Insert(binary(gdcm::Tag(0x0020, 0x9057), gdcm::VR::UL, &f.stackPosition, 4));
    if (f.temporalIndex > 0)
      content.Insert(binary(gdcm::Tag(0x0020, 0x9128), gdcm::VR::UL, &f.temporalIndex, 4));
    frame.Insert(sequenceOf(gdcm::Tag(0x0020, 0x9111), {content}));
    if (f.triggerTime >= 0)
      frame.Insert(wrap(gdcm::Tag(0x0018, 0x9118),
                        binary(gdcm::Tag(0x0020, 0x9153), gdcm::VR::FD, &f.triggerTime, 8)));
    frame.Insert(
        wrap(gdcm::Tag(0x0020, 0x9113), text(gdcm::Tag(0x0020, 0x0032), gdcm::VR::DS,
                                             numbers({f.position.x, f.position.y, f.position.z}))));
    gdcm::DataSet transform;
    transform.Insert(text(gdcm::Tag(0x0028, 0x1052), gdcm::VR::DS, numbers({f.intercept})));
    transform.Insert(text(gdcm::Tag(0x0028, 0x1053), gdcm::VR::DS, numbers({f.slope})));
    transform.Insert(text(gdcm::Tag(0x0028, 0x1054), gdcm::VR::LO, ct ? "HU" : "US"));
    frame.Insert(sequenceOf(gdcm::Tag(0x0028, 0x9145), {transform}));
    frame.Insert(wrap(ct ? gdcm::Tag(0x0018, 0x9329) : gdcm::Tag(0x0018, 0x9226),
                      text(gdcm::Tag(0x0008, 0x9007), gdcm::VR::CS, f.frameType)));
    perFrame.push_back(frame);
  }
  ds.Insert(sequenceOf(gdcm::Tag(0x5200, 0x9230), perFrame));
  if (e.dimensionIndex) {
    std::vector<gdcm::DataSet> dims;
    for (const auto& [pointer, group] :
         {std::pair{gdcm::Tag(0x0008, 0x9007), gdcm::Tag(0x0018, ct ? 0x9329 : 0x9226)},
          std::pair{gdcm::Tag(0x0020, 0x9057), gdcm::Tag(0x0020, 0x9111)}}) {
      gdcm::DataSet item;
      const std::uint16_t at[2] = {pointer.GetGroup(), pointer.GetElement()};
      const std::uint16_t gp[2] = {group.GetGroup(), group.GetElement()};
      item.Insert(binary(gdcm::Tag(0x0020, 0x9165), gdcm::VR::AT, at, 4));
      item.Insert(binary(gdcm::Tag(0x0020, 0x9167), gdcm::VR::AT, gp, 4));
      dims.push_back(item);
    }
    ds.Insert(sequenceOf(gdcm::Tag(0x0020, 0x9222), dims));
  }
  ds.Insert(binary(gdcm::Tag(0x7fe0, 0x0010), gdcm::VR::OW, pixels.data(), pixels.size() * 2));
  gdcm::FileMetaInformation& meta = writer.GetFile().GetHeader();
  meta.SetDataSetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
  meta.FillFromDataSet(ds);
  writer.SetFileName(path.c_str());
  if (!writer.Write()) throw std::runtime_error("GDCM cannot write " + path);
}

}  // namespace voxwall::test
