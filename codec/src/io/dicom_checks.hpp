// The checks a DICOM file passes before GDCM reads it (io/dicom_checks.cpp), for io/dicom.cpp:
// each refuses, with a FormatError, a file on which Debian's GDCM would abort the program or
// allocate far more than the file holds. Also the parsing of DICOM text values both files use.
#pragma once

#include <gdcmTag.h>

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace voxwall::codec::dicom {

// The image attributes the checks read.
inline const gdcm::Tag kRows{0x0028, 0x0010}, kColumns{0x0028, 0x0011}, kSamples{0x0028, 0x0002},
    kBitsAllocated{0x0028, 0x0100}, kPixelData{0x7fe0, 0x0010};

// A text value without DICOM's padding (spaces, NUL after UIDs); empty for nullptr.
std::string trimmed(const char* value);
// "a\b\c" as numbers; empty when any of them is not a finite number.
std::vector<double> numbersOf(const std::string& text);
// The most digits after the decimal point among "a\b\c" (16 for none given or an exponent):
// how finely a scanner rounded the values it wrote (it drops trailing zeros: "7" next to "12.3").
int decimalsOf(const std::string& text);
// `v` with `digits` digits after the point, for messages.
std::string fixed(double v, int digits = 2);
// A file's text for a one-line message: printable ASCII, anything else '?', at most `maxChars`.
std::string printable(const std::string& text, std::size_t maxChars = 64);

// What checkElements() found of a file.
struct CheckedFile {
  std::string transferSyntax;  // the UID of (0002,0010)
  bool hasPixelData = false;
  bool fragments = false;  // the Pixel Data is a sequence of fragments (undefined length)
  std::uint64_t end = 0;   // where the Pixel Data ends (the file's size when it has none)
};

// Walks the File Meta Information, the data set's elements (and their sequences) up to the Pixel
// Data, and the Pixel Data element (its fragments when encapsulated) by their lengths. Call it
// before any GDCM reader (the scanner too) sees the file; GDCM may read it up to `end`.
CheckedFile checkElements(const std::string& file);

// A compressed file's first fragment starts as its transfer syntax's stream does, and the
// stream's frame header gives the header's image size. Reads `stream` when given, else `file`.
void checkCompressedStart(const std::string& file, std::istream* stream);

// An image with functional groups names its orientation where GDCM looks for it, and a
// Recognition Code is ACR-NEMA's; call after checkElements() checked the file.
void checkImageHeader(const std::string& file);

}  // namespace voxwall::codec::dicom
