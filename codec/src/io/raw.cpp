// Headerless raw voxels: the user states dims, type, endianness and a header to skip.
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {

void checkRawFile(const std::string& path, const RawLayout& layout) {
  if (layout.dims.x <= 0 || layout.dims.y <= 0 || layout.dims.z <= 0)
    throw FormatError(path, "raw files need their dimensions (--dims X,Y,Z)");
  checkDims(layout.dims, path);
  std::error_code ec;
  const auto fileBytes = std::filesystem::file_size(path, ec);
  if (ec) throw FormatError(path, ec.message());
  // Sizes first: a wrong --dims must not allocate gigabytes before saying so.
  const std::uint64_t need =
      layout.headerBytes + std::uint64_t(layout.dims.x) * std::uint64_t(layout.dims.y) *
                               std::uint64_t(layout.dims.z) * scalarBytes(layout.type);
  if (fileBytes < need)
    throw FormatError(
        path, "truncated: " + std::to_string(fileBytes) + " bytes, but " +
                  std::to_string(layout.dims.x) + "x" + std::to_string(layout.dims.y) + "x" +
                  std::to_string(layout.dims.z) + " " + std::string(scalarName(layout.type)) +
                  " needs " + std::to_string(need));
  if (fileBytes > need)
    throw FormatError(
        path, std::to_string(fileBytes) + " bytes, but " + std::to_string(layout.dims.x) + "x" +
                  std::to_string(layout.dims.y) + "x" + std::to_string(layout.dims.z) + " " +
                  std::string(scalarName(layout.type)) + " needs " + std::to_string(need) +
                  " (wrong dimensions or type, or give --header-bytes)");
}

Volume readRaw(const std::string& path, const RawLayout& layout) {
  checkRawFile(path, layout);
  Volume v = Volume::allocate(layout.dims, layout.type, layout.spacing);
  v.orientation = layout.orientation;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path, std::strerror(errno));
  in.seekg(std::streamoff(layout.headerBytes));
  in.read(reinterpret_cast<char*>(v.data.data()), std::streamsize(v.data.size()));
  if (!in) throw FormatError(path, "read failed");
  const std::size_t width = scalarBytes(layout.type);
  if (layout.bigEndian && width > 1)
    for (std::size_t i = 0; i < v.data.size(); i += width)
      std::reverse(v.data.begin() + std::ptrdiff_t(i), v.data.begin() + std::ptrdiff_t(i + width));
  v.computeRange();
  return v;
}

void writeRaw(const Volume& volume, const std::string& path) {
  writeFileAtomically(path, volume.data);
}

}  // namespace voxwall::codec
