// The checks of compressed pixel data before GDCM decodes it (declared in dicom_checks.hpp):
// the first fragment starts as its transfer syntax's stream does, and the stream's frame header
// gives the image the DICOM header describes, in a kind of frame GDCM's codecs decode.
#include <gdcmReader.h>
#include <gdcmSequenceOfFragments.h>

#include <cstdint>
#include <istream>
#include <voxwall/core/errors.hpp>

#include "dicom_checks.hpp"

namespace voxwall::codec::dicom {

namespace {

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
        // GDCM's JPEG codecs know baseline, extended, progressive (8 or 12 bits) and lossless
        // Huffman frames; they assert on others (found by the DICOM fuzz target: a progressive
        // frame of 16 bits).
        const bool known = marker == 0xf7 || marker == 0xc0 || marker == 0xc1 || marker == 0xc3 ||
                           (marker == 0xc2 && (precision == 8 || precision == 12));
        if (!known)
          throw FormatError(file, "its JPEG stream is a kind of frame GDCM does not decode (SOF" +
                                      std::to_string(marker - 0xc0) + " of " +
                                      std::to_string(precision) + " bits)");
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

}  // namespace

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

}  // namespace voxwall::codec::dicom
