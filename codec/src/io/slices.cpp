// A stack of 2D greyscale slices through OpenImageIO: a directory of images (sorted by name,
// numbers compared by value) or one multi-page TIFF.
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <filesystem>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {
namespace {

namespace fs = std::filesystem;

// "slice2" before "slice10".
bool naturalLess(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit((unsigned char)a[i]) && std::isdigit((unsigned char)b[j])) {
      std::size_t i2 = i, j2 = j;
      while (i2 < a.size() && std::isdigit((unsigned char)a[i2])) ++i2;
      while (j2 < b.size() && std::isdigit((unsigned char)b[j2])) ++j2;
      std::string na = a.substr(i, i2 - i), nb = b.substr(j, j2 - j);
      na.erase(0, std::min(na.find_first_not_of('0'), na.size()));
      nb.erase(0, std::min(nb.find_first_not_of('0'), nb.size()));
      if (na.size() != nb.size()) return na.size() < nb.size();
      if (na != nb) return na < nb;
      i = i2, j = j2;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i, ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

bool isSliceImage(const fs::path& p) {
  const std::string ext = extensionOf(p.string());
  return ext == "tif" || ext == "tiff" || ext == "png" || ext == "pgm" || ext == "exr";
}

ScalarType typeFor(const OIIO::TypeDesc& format) {
  if (format == OIIO::TypeDesc::UINT8) return ScalarType::UInt8;
  if (format == OIIO::TypeDesc::UINT16) return ScalarType::UInt16;
  if (format == OIIO::TypeDesc::INT16) return ScalarType::Int16;
  return ScalarType::Float32;
}

OIIO::TypeDesc oiioType(ScalarType t) {
  switch (t) {
    case ScalarType::UInt8:
      return OIIO::TypeDesc::UINT8;
    case ScalarType::UInt16:
      return OIIO::TypeDesc::UINT16;
    case ScalarType::Int16:
      return OIIO::TypeDesc::INT16;
    case ScalarType::Float32:
      return OIIO::TypeDesc::FLOAT;
  }
  return OIIO::TypeDesc::FLOAT;
}

// Appends one slice's pixels to `v` at slice z after checking it matches the first slice.
void readSlice(OIIO::ImageInput& in, const std::string& file, int subimage, Volume& v, int z) {
  const OIIO::ImageSpec& spec = in.spec();
  if (spec.nchannels != 1)
    throw FormatError(file, "has " + std::to_string(spec.nchannels) +
                                " channels; slices must be single-channel greyscale");
  if (spec.width != v.dims.x || spec.height != v.dims.y || spec.depth > 1)
    throw FormatError(file, "is " + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                                " but the first slice is " + std::to_string(v.dims.x) + "x" +
                                std::to_string(v.dims.y));
  std::byte* dst = v.data.data() + std::size_t(z) * std::size_t(v.dims.x) * std::size_t(v.dims.y) *
                                       scalarBytes(v.type);
  if (!in.read_image(subimage, 0, 0, 1, oiioType(v.type), dst))
    throw FormatError(file, "cannot read pixels: " + in.geterror());
}

}  // namespace

Volume readSliceStack(const std::string& path) {
  std::vector<std::string> files;
  if (fs::is_directory(path)) {
    std::error_code ec;
    for (fs::directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec))
      if (it->is_regular_file(ec) && isSliceImage(it->path())) files.push_back(it->path().string());
    if (ec) throw FormatError(path, "cannot list the slices: " + ec.message());
    std::sort(files.begin(), files.end(), naturalLess);
    if (files.empty())
      throw FormatError(path, "directory holds no .tif/.tiff/.png/.pgm/.exr slices");
  } else {
    files.push_back(path);
  }

  auto first = OIIO::ImageInput::open(files[0]);
  if (!first) throw FormatError(files[0], "cannot open image: " + OIIO::geterror());
  int pages = 1;
  if (files.size() == 1) {
    while (first->seek_subimage(pages, 0)) ++pages;
    first->seek_subimage(0, 0);
  }
  const OIIO::ImageSpec spec0 = first->spec();
  const int depth = files.size() > 1 ? int(files.size()) : pages;
  const glm::ivec3 dims(spec0.width, spec0.height, depth);
  checkDims(dims, path);
  Volume v = Volume::allocate(dims, typeFor(spec0.format));
  if (files.size() > 1) {
    first.reset();
    for (int z = 0; z < depth; ++z) {
      auto in = OIIO::ImageInput::open(files[std::size_t(z)]);
      if (!in) throw FormatError(files[std::size_t(z)], "cannot open image: " + OIIO::geterror());
      readSlice(*in, files[std::size_t(z)], 0, v, z);
    }
  } else {
    for (int z = 0; z < depth; ++z) {
      if (!first->seek_subimage(z, 0))
        throw FormatError(path, "cannot seek to page " + std::to_string(z));
      readSlice(*first, path + " page " + std::to_string(z), z, v, z);
    }
  }
  v.computeRange();
  return v;
}

}  // namespace voxwall::codec
