#include "support/dicom_writer.hpp"

#include <gdcmAttribute.h>
#include <gdcmImageChangeTransferSyntax.h>
#include <gdcmImageWriter.h>
#include <gdcmTrace.h>

#include <cstring>
#include <stdexcept>

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
  put(gdcm::Attribute<0x0008, 0x0060>{multi ? "OT" : "CT"});
  put(gdcm::Attribute<0x0008, 0x103e>{s.description.c_str()});
  put(gdcm::Attribute<0x0020, 0x000e>{s.seriesUid.c_str()});
  put(gdcm::Attribute<0x0020, 0x0013>{s.instance});
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
}

}  // namespace voxwall::test
