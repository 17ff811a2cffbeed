// The checks a DICOM file passes before GDCM reads it. Debian's GDCM is built with its
// assertions on and trusts the lengths it reads: on a corrupt file it aborts the program or
// allocates gigabytes. So every file's elements, sequences and pixel-data fragments are walked
// here by their tags and lengths first (never their meaning), and a compressed stream's own frame
// header is compared with the image it claims to be. Each check names the input of the DICOM fuzz
// target that led to it.
#include "dicom_checks.hpp"

#include <gdcmDicts.h>
#include <gdcmFileMetaInformation.h>
#include <gdcmGlobal.h>
#include <gdcmMediaStorage.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfFragments.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmUIDs.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <voxwall/core/errors.hpp>

namespace voxwall::codec::dicom {
namespace {

namespace fs = std::filesystem;

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
      if (depth == 0 && tag == stop) {
        // GDCM reads a header up to the first element at or past the Pixel Data's tag, and the
        // whole file past it: an element DICOM orders after the Pixel Data but written before it
        // hides what follows from the header checks (found by the DICOM fuzz target: functional
        // groups after (8028,0102) made GDCM's spacing code assert).
        if (late_.first)
          fail(at, "has an element (" + hex(late_.first) + ") at byte " +
                       std::to_string(late_.second) +
                       " before its Pixel Data that DICOM orders after it");
        return at;
      }
      if (depth == 0 && stop && tag > stop && !late_.first) late_ = {tag, at};
      // GDCM reads (00FF,4AA5) as pixel data running to the end of the file, asserting on what
      // it finds there (a workaround for one scanner's broken files).
      if (tag == 0x00ff4aa5u) fail(at, "has element (00FF,4AA5), which GDCM reads as pixel data");
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
        // GDCM shortens some values of a size no value of their VR has (a UL of 6 bytes in
        // group 0009 is read as 4) and then reads the rest of the file from the wrong place.
        const std::size_t size = numberSize(vr);
        if (size > 1 && length != 0xffffffffu && length % size != 0)
          fail(at, "has an element (" + hex(tag) + ") at byte " + std::to_string(at) + " of " +
                       std::to_string(length) + " bytes, not a whole number of " + vr + " values");
      } else {
        length = le32(h + 4);
        // Implicit VR: GDCM reads a sequence's items when its dictionary says SQ.
        sequence = dictionaryVr(tag) == gdcm::VR::SQ;
        // GDCM reads 10 bytes of an implicit value of 13 (a workaround for one vendor's files)
        // and then reads the rest of the file from the wrong place.
        if (length == 13 && tag != 0x00080070u && tag != 0x00080080u)
          fail(at, "has an element (" + hex(tag) + ") at byte " + std::to_string(at) +
                       " of 13 bytes (DICOM values have an even length)");
      }
      if (length == 0xffffffffu) {
        // Pixel data of undefined length holds fragments, whose bytes are not elements (an
        // icon's too, in a sequence); an undefined-length UN holds implicit VR little endian
        // elements (PS3.5 6.2.2). GDCM reads nothing else of undefined length but a sequence:
        // it asserts that such an element is UN.
        const bool isUn = explicit_ && h[4] == 'U' && h[5] == 'N';
        const bool fragments = tag == 0x7fe00010u;
        // A public element read as items although its dictionary says it holds a value: GDCM's
        // image code then finds no value where it dereferences one.
        const gdcm::VR known = isUn ? dictionaryVr(tag) : gdcm::VR(gdcm::VR::INVALID);
        if (isUn && !fragments && known != gdcm::VR::INVALID && known != gdcm::VR::SQ)
          fail(at, "has an element (" + hex(tag) + ") at byte " + std::to_string(at) +
                       " stored as UN of undefined length where DICOM says it holds a value");
        if (explicit_ && !sequence && !isUn && !fragments)
          fail(at, "has an element (" + hex(tag) + ") at byte " + std::to_string(at) +
                       " of undefined length that is neither a sequence nor pixel data");
        const bool saved = explicit_;
        if (isUn && !fragments) explicit_ = false;
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
  // The bytes of one value of a numeric VR (0 for the others).
  static std::size_t numberSize(const std::string& vr) {
    if (vr == "US" || vr == "SS") return 2;
    if (vr == "UL" || vr == "SL" || vr == "FL" || vr == "AT") return 4;
    if (vr == "FD" || vr == "SV" || vr == "UV") return 8;
    return 0;
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
  std::pair<std::uint32_t, std::uint64_t> late_{0, 0};  // the first element past `stop`, at
};

// Every transfer syntax voxwall reads is explicit VR little endian but one.
bool isExplicitVr(const std::string& transferSyntax) {
  return transferSyntax != "1.2.840.10008.1.2";
}

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
  // GDCM guesses the encoding of a data set whose meta group names no transfer syntax; the walk
  // must read the elements as GDCM will, so such a file is refused (the UID is required).
  if (uid.empty())
    throw FormatError(file, "its File Meta Information names no Transfer Syntax UID (0002,0010)");
  if (uid == "1.2.840.10008.1.2.1.99" || uid == "1.2.840.10008.1.2.2")
    throw FormatError(file, "uses transfer syntax " + uid +
                                " (deflated or big endian), which voxwall does not read");
  // GDCM's image reader asserts on a transfer syntax it does not know (see checkImageHeader).
  if (gdcm::TransferSyntax::GetTSType(uid.c_str()) == gdcm::TransferSyntax::TS_END)
    throw FormatError(file, "uses transfer syntax " + uid + ", which GDCM does not know");
  return ElementWalk(file, fileSize, isExplicitVr(uid))
      .list(dataSet, fileSize, 0, false, 0x7fe00010u);
}

}  // namespace

// The items of encapsulated (compressed) Pixel Data, walked here before GDCM reads any of them:
// GDCM allocates what each fragment claims, and a 1 KiB file whose fragment claimed 1 GiB cost
// 27 s and 3.2 GB (0xfffffff0: 142 s and 12.7 GB) and was then accepted. Each item must be an
// Item (FFFE,E000) of defined length that ends inside the file, and a Sequence Delimitation Item
// (FFFE,E0DD) must close them.
// Refuses a file whose pixel data runs past its end (GDCM, walking to it, fell back to other
// encodings on such files and aborted on an assertion). GDCM's scanner reads the element after
// the last tag it looks for, which may be the Pixel Data: a 584-byte file whose Pixel Data claimed
// 4 GiB made it allocate that (found by the DICOM fuzz target), so files are checked whole before
// the scanner too.
CheckedFile checkElements(const std::string& file) {
  CheckedFile out;
  std::string& uid = out.transferSyntax;
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
  if (!readAt(at, h, 8) || le16(h) != 0x7fe0 || le16(h + 2) != 0x0010) {
    out.end = size;  // the walk went to the end
    return out;
  }
  out.hasPixelData = true;
  // (GDCM ignores the two reserved bytes after an explicit VR; so does this.) Another VR there
  // makes GDCM fall back to readers for broken files, which assert (found by the DICOM fuzz
  // target: a VR of two zero bytes).
  const bool explicitVr = isExplicitVr(uid);
  const std::string vr{char(h[4]), char(h[5])};
  if (explicitVr && vr != "OB" && vr != "OW" && vr != "UN")
    throw FormatError(file,
                      "its Pixel Data is stored with a value representation other than "
                      "OB, OW or UN");
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
    out.end = at + length;
    return out;
  }
  if (!compressed)
    throw FormatError(file, "its pixel data is a sequence of fragments but its transfer syntax " +
                                (uid.empty() ? std::string("(none)") : uid) +
                                " is not a compressed one");
  out.fragments = true;
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
      out.end = at + 8;
      return out;
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

namespace {

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

// A UID with its name where GDCM knows it: "1.2.840.10008.5.1.4.1.1.4.2 (MR Spectroscopy
// Storage)".
std::string uidName(const char* uid) {
  const std::string text = uid ? uid : "";
  gdcm::UIDs known;
  if (!known.SetFromUID(text.c_str()) || !known.GetName()) return text;
  return text + " (" + known.GetName() + ")";
}

}  // namespace

// An image with functional groups (enhanced, usually multi-frame) must name its orientation
// where GDCM looks for it; a Recognition Code (0008,0010, ACR-NEMA's) must be one GDCM 3.0
// knows: it asserts on any other (found by the DICOM fuzz target). Call after checkElements().
void checkImageHeader(const std::string& file) {
  gdcm::Reader head;
  head.SetFileName(file.c_str());
  if (!head.ReadUpToTag(kPixelData, {kPixelData}))
    throw FormatError(file, "GDCM cannot read it as DICOM (corrupt header)");
  const gdcm::DataSet& ds = head.GetFile().GetDataSet();
  // GDCM's image reader asserts (Debian builds keep assertions) where it should fail on a
  // transfer syntax it does not know, or a Media Storage SOP Class that is not an image when the
  // SOP Class UID names none it knows (found by the DICOM fuzz target: MR Spectroscopy).
  const gdcm::FileMetaInformation& meta = head.GetFile().GetHeader();
  if (meta.GetDataSetTransferSyntax() == gdcm::TransferSyntax::TS_END)
    throw FormatError(file, "names a transfer syntax GDCM does not know");
  const gdcm::MediaStorage storage = meta.GetMediaStorage();
  if (storage != gdcm::MediaStorage::MS_END && !gdcm::MediaStorage::IsImage(storage) &&
      !gdcm::MediaStorage::IsImage(ds.GetMediaStorage()))
    throw FormatError(file, "is not an image: its Media Storage SOP Class (0002,0002) is " +
                                uidName(gdcm::MediaStorage::GetMSString(storage)));
  // A palette colour image holds indices into its colour tables, not values; GDCM asserts where
  // the tables are missing (found by the DICOM fuzz target).
  const gdcm::Tag photometric(0x0028, 0x0004);
  if (ds.FindDataElement(photometric)) {
    const gdcm::ByteValue* bv = ds.GetDataElement(photometric).GetByteValue();
    const std::string code =
        bv ? trimmed(std::string(bv->GetPointer(), bv->GetLength()).c_str()) : "";
    if (!code.empty() && code != "MONOCHROME1" && code != "MONOCHROME2")
      throw FormatError(file, "has Photometric Interpretation " + code +
                                  "; voxwall reads greyscale DICOM (MONOCHROME1 or MONOCHROME2)");
  }
  const gdcm::Tag recognition(0x0008, 0x0010);
  if (ds.FindDataElement(recognition) && !ds.GetDataElement(recognition).IsEmpty()) {
    const gdcm::ByteValue* bv = ds.GetDataElement(recognition).GetByteValue();
    const std::string code = bv ? std::string(bv->GetPointer(), bv->GetLength()) : "";
    if (code.rfind("ACR-NEMA", 0) != 0 && code.rfind("ACRNEMA", 0) != 0 &&
        code.rfind("MIPS 2.0", 0) != 0)
      throw FormatError(file,
                        "has a Recognition Code (0008,0010) that is not ACR-NEMA's (a retired "
                        "element GDCM reads only as that)");
  }
  if ((ds.FindDataElement(gdcm::Tag(0x5200, 0x9229)) ||
       ds.FindDataElement(gdcm::Tag(0x5200, 0x9230))) &&
      !hasFrameOrientation(ds))
    throw FormatError(file,
                      "has functional groups but no Image Orientation (Patient) of six numbers "
                      "in them");
}

std::string trimmed(const char* value) {
  if (!value) return {};
  std::string s(value);
  static const std::string blank(" \t\r\n\0", 5);  // DICOM pads with spaces (UIDs with NUL)
  const auto first = s.find_first_not_of(blank);
  if (first == std::string::npos) return {};
  return s.substr(first, s.find_last_not_of(blank) - first + 1);
}

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

int decimalsOf(const std::string& text) {
  int most = -1;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, '\\')) {
    item = trimmed(item.c_str());
    if (item.empty()) continue;
    if (item.find_first_of("eE") != std::string::npos) return 16;
    const auto dot = item.find('.');
    most = std::max(most, dot == std::string::npos ? 0 : int(item.size() - dot - 1));
  }
  return most < 0 ? 16 : most;
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::string printable(const std::string& text, std::size_t maxChars) {
  std::string out;
  for (const char c : text) {
    if (out.size() == maxChars) return out + "...";
    out += c >= 0x20 && c < 0x7f ? c : '?';
  }
  return out;
}

}  // namespace voxwall::codec::dicom
