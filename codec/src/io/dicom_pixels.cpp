#include "dicom_pixels.hpp"

#include <gdcmImageReader.h>
#include <gdcmSequenceOfFragments.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/mat3x3.hpp>
#include <limits>
#include <map>
#include <sstream>
#include <voxwall/core/errors.hpp>

#include "../file_util.hpp"
#include "dicom_checks.hpp"

namespace voxwall::codec::dicom {
namespace {

namespace fs = std::filesystem;

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

bool integral(double v) { return std::abs(v - std::round(v)) < 1e-9; }

}  // namespace

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

Decoded decode(const std::string& file, std::vector<std::byte>& buffer, std::size_t offset,
               std::size_t expectBytes) {
  const dicom::CheckedFile checked = checkElements(file);
  if (!checked.hasPixelData) throw FormatError(file, "has no Pixel Data");
  const bool encapsulated = checked.fragments;
  const std::size_t end = checked.end;
  checkImageHeader(file);
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

namespace {

// Frames of enhanced files: each file decoded once, whole, its frames copied into place, each
// with its own rescale.
std::vector<Decoded> decodeFrames(const std::vector<SliceHeader>& slices, glm::ivec3 dims,
                                  std::vector<std::byte>& stored) {
  std::map<std::string, std::vector<std::size_t>> byFile;  // the z of each file's frames
  for (std::size_t z = 0; z < slices.size(); ++z) byFile[slices[z].source].push_back(z);
  std::vector<Decoded> decoded(slices.size());
  std::size_t frameBytes = 0;
  std::string firstFile;
  std::vector<std::byte> whole;
  for (const auto& [file, zs] : byFile) {
    whole.clear();
    const Decoded d = decode(file, whole, 0, 0);
    const int frames = slices[zs.front()].frames;
    if (d.dims[0] != unsigned(dims.x) || d.dims[1] != unsigned(dims.y) ||
        d.dims[2] != unsigned(frames))
      throw FormatError(file, "decodes to " + std::to_string(d.dims[0]) + "x" +
                                  std::to_string(d.dims[1]) + "x" + std::to_string(d.dims[2]) +
                                  " where its header says " + std::to_string(dims.x) + "x" +
                                  std::to_string(dims.y) + "x" + std::to_string(frames));
    if (firstFile.empty()) {
      firstFile = file;
      frameBytes = std::size_t(dims.x) * std::size_t(dims.y) * storedBytes(d.stored);
      stored.assign(frameBytes * slices.size(), std::byte{0});
    } else if (d.stored != decoded[byFile.begin()->second.front()].stored) {
      throw FormatError(
          file, "stores its pixels in another type than " + firstFile + " of the same series");
    }
    for (const std::size_t z : zs) {
      const SliceHeader& s = slices[z];
      std::memcpy(stored.data() + z * frameBytes, whole.data() + std::size_t(s.frame) * frameBytes,
                  frameBytes);
      decoded[z] = d;
      if (s.rescaled) decoded[z].slope = s.slope, decoded[z].intercept = s.intercept;
    }
  }
  return decoded;
}

}  // namespace

std::vector<Decoded> decodeSlices(const std::vector<SliceHeader>& slices, glm::ivec3 dims,
                                  std::vector<std::byte>& stored) {
  if (!slices.empty() && slices.front().frame >= 0) return decodeFrames(slices, dims, stored);
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
      throw FormatError(slices[z].file, "stores its pixels in another type than " +
                                            slices.front().file + " of the same series");
    if (z == 0) {
      sliceBytes = std::size_t(dims.x) * std::size_t(dims.y) * storedBytes(d.stored);
      stored.reserve(sliceBytes * slices.size());
    }
  }
  return decoded;
}

}  // namespace voxwall::codec::dicom
