// The checks a DICOM file passes before GDCM reads it (io/dicom_checks.cpp), for io/dicom.cpp:
// each refuses, with a FormatError, a file on which Debian's GDCM would abort the program or
// allocate far more than the file holds. Also the parsing of DICOM text values both files use.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace voxwall::codec::dicom {

// A text value without DICOM's padding (spaces, NUL after UIDs); empty for nullptr.
std::string trimmed(const char* value);
// "a\b\c" as numbers; empty when any of them is not a finite number.
std::vector<double> numbersOf(const std::string& text);

// Walks the File Meta Information and the data set's elements (and their sequences) by their
// lengths up to the Pixel Data; returns where it stopped (the Pixel Data's tag, or the file's
// end). `transferSyntax`, when given, receives the UID of (0002,0010).
std::uint64_t walkToPixelData(const std::string& file, std::string* transferSyntax = nullptr);

// Walks the Pixel Data element (its fragments when encapsulated); returns where it ends.
// `fragments` says whether it is a sequence of fragments (undefined length).
std::uint64_t pixelDataEnd(const std::string& file, bool& fragments);

// A compressed file's first fragment starts as its transfer syntax's stream does, and the
// stream's frame header gives the header's image size. Reads `stream` when given, else `file`.
void checkCompressedStart(const std::string& file, std::istream* stream);

// An image with functional groups names its orientation where GDCM looks for it; call after
// pixelDataEnd() checked the file.
void checkFunctionalGroups(const std::string& file);

}  // namespace voxwall::codec::dicom
