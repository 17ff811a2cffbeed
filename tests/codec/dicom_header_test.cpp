// Headers on which GDCM's image reader asserts (Debian builds keep assertions, so the program
// aborts) instead of failing: the DICOM reader refuses them in one line first. Each case was
// found by the DICOM fuzz target; the files are a multi-frame image written here with GDCM and
// then edited byte by byte.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <voxwall/codec/volume_io.hpp>

#include "support/dicom_writer.hpp"
#include "support/format_error_expect.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using voxwall::test::expectFormatError;
using voxwall::test::readFile;
using voxwall::test::TempDir;
using voxwall::test::writeFile;

namespace {

// Multi-frame Grayscale Word Secondary Capture, 6 x 5 x 2: the kind of file the fuzz target
// started from.
std::string writeFrames(const TempDir& dir, const std::string& name) {
  voxwall::test::DicomSlice s;
  s.columns = 6, s.rows = 5, s.frames = 2, s.isUnsigned = true;
  for (int i = 0; i < s.columns * s.rows * s.frames; ++i) s.pixels.push_back(std::int16_t(i));
  const std::string file = dir.path(name);
  voxwall::test::writeDicom(file, s);
  return file;
}

std::size_t find(const std::string& bytes, const std::string& what) {
  const auto at = bytes.find(what);
  EXPECT_NE(at, std::string::npos);
  return at == std::string::npos ? 0 : at;
}

// Replaces the value of the meta group's UI element `element` (0002,xxxx) with `uid`, padded to
// an even length, and corrects the element's and the group's lengths.
std::string withMetaUid(std::string bytes, char element, std::string uid) {
  if (uid.size() % 2) uid.push_back('\0');
  const std::size_t at = find(bytes, std::string("\x02\x00", 2) + element + "\x00UI");
  const std::size_t old = std::uint8_t(bytes[at + 6]) | std::uint8_t(bytes[at + 7]) << 8;
  bytes.replace(at + 8, old, uid);
  bytes[at + 6] = char(uid.size()), bytes[at + 7] = 0;
  const std::size_t group = find(bytes, std::string("\x02\x00\x00\x00UL\x04\x00", 8)) + 8;
  std::uint32_t length;
  std::memcpy(&length, &bytes[group], 4);
  length = std::uint32_t(length + uid.size() - old);
  std::memcpy(&bytes[group], &length, 4);
  return bytes;
}

// Replaces the value of the data set's element `tag` (explicit VR, a 2-byte length) with `value`,
// padded with a space to an even length.
std::string withValue(std::string bytes, const std::string& tag, std::string value) {
  if (value.size() % 2) value.push_back(' ');
  const std::size_t at = bytes.rfind(tag);
  EXPECT_NE(at, std::string::npos);
  if (at == std::string::npos) return bytes;
  const std::size_t old = std::uint8_t(bytes[at + 6]) | std::uint8_t(bytes[at + 7]) << 8;
  bytes.replace(at + 8, old, value);
  bytes[at + 6] = char(value.size()), bytes[at + 7] = 0;
  return bytes;
}

}  // namespace

TEST(DicomHeader, TheFramesReadBeforeAnyEdit) {
  TempDir dir;
  const auto v = codec::readVolume(writeFrames(dir, "frames.dcm"));
  EXPECT_EQ(v.dims, glm::ivec3(6, 5, 2));
}

// An element ordered after the Pixel Data but written before it: GDCM's header read stops there,
// its image read does not (functional groups after it made GDCM's spacing code assert).
TEST(DicomHeader, AnElementOrderedAfterThePixelDataButWrittenBeforeItIsRefused) {
  TempDir dir;
  const std::string file = writeFrames(dir, "late.dcm");
  std::string bytes = readFile(file);
  const std::string late("\x28\x80\x02\x01US\x02\x00\x0f\x00", 10);        // (8028,0102) US 15
  const std::size_t at = find(bytes, std::string("\x28\x00\x01\x01", 4));  // Bits Stored
  writeFile(file, bytes.substr(0, at) + late + bytes.substr(at));
  expectFormatError([&] { codec::readVolume(file); }, file,
                    "has an element (8028,0102) at byte " + std::to_string(at) +
                        " before its Pixel Data that DICOM orders after it");
}

// A Media Storage SOP Class that is not an image (MR Spectroscopy) and a SOP Class UID GDCM does
// not know: GDCM asserted instead of failing.
TEST(DicomHeader, AMediaStorageThatIsNotAnImageIsRefused) {
  TempDir dir;
  const std::string file = writeFrames(dir, "spectroscopy.dcm");
  std::string bytes = withMetaUid(readFile(file), '\x02', "1.2.840.10008.5.1.4.1.1.4.2");
  const std::size_t sop = find(bytes, std::string("\x08\x00\x16\x00UI", 6)) + 8;
  bytes[sop] = '9';  // 9.2.840...: no SOP class GDCM knows
  writeFile(file, bytes);
  expectFormatError([&] { codec::readVolume(file); }, file,
                    "is not an image: its Media Storage SOP Class (0002,0002) is "
                    "1.2.840.10008.5.1.4.1.1.4.2 (MR Spectroscopy Storage)");
}

TEST(DicomHeader, ATransferSyntaxGdcmDoesNotKnowIsRefused) {
  TempDir dir;
  const std::string file = writeFrames(dir, "syntax.dcm");
  writeFile(file, withMetaUid(readFile(file), '\x10', "1.2.840.10008.1.2.1.77"));
  expectFormatError([&] { codec::readVolume(file); }, file,
                    "uses transfer syntax 1.2.840.10008.1.2.1.77, which GDCM does not know");
}

// A palette colour image without its colour tables: GDCM asserted. Any palette image holds
// indices, not values: refused.
TEST(DicomHeader, APaletteColourImageIsRefused) {
  TempDir dir;
  const std::string file = writeFrames(dir, "palette.dcm");
  writeFile(file, withValue(readFile(file),
                            std::string("\x28\x00\x04\x00"
                                        "CS",
                                        6),
                            "PALETTE COLOR"));
  expectFormatError([&] { codec::readVolume(file); }, file,
                    "has Photometric Interpretation PALETTE COLOR; voxwall reads greyscale DICOM");
}

// A JPEG frame GDCM's codecs do not know (a progressive frame of 16 bits): GDCM asserted.
TEST(DicomHeader, AJpegFrameGdcmDoesNotDecodeIsRefused) {
  TempDir dir;
  voxwall::test::DicomSlice s;
  s.columns = 6, s.rows = 5, s.syntax = voxwall::test::DicomSyntax::JpegLossless;
  for (int i = 0; i < 30; ++i) s.pixels.push_back(std::int16_t(i * 9));
  const std::string file = dir.path("progressive.dcm");
  voxwall::test::writeDicom(file, s);
  EXPECT_EQ(codec::readVolume(file).dims, glm::ivec3(6, 5, 1));
  std::string bytes = readFile(file);
  const std::size_t sof = bytes.find("\xff\xc3", bytes.rfind(std::string("\xe0\x7f\x10\x00", 4)));
  ASSERT_NE(sof, std::string::npos);
  bytes[sof + 1] = char(0xc2);
  writeFile(file, bytes);
  expectFormatError([&] { codec::readVolume(file); }, file,
                    "its JPEG stream is a kind of frame GDCM does not decode (SOF2 of 16 bits)");
}
