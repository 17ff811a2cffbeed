// A stack of 2D greyscale slices through OpenImageIO (core's image-file module): a directory of
// images (sorted by name, numbers compared by value) or one multi-page TIFF.
#include <algorithm>
#include <filesystem>
#include <memory>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/image_files.hpp>

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

ScalarType typeFor(image_files::Pixel format) {
  switch (format) {
    case image_files::Pixel::UInt8:
      return ScalarType::UInt8;
    case image_files::Pixel::UInt16:
      return ScalarType::UInt16;
    case image_files::Pixel::Int16:
      return ScalarType::Int16;
    case image_files::Pixel::Float32:
    case image_files::Pixel::Other:
      break;
  }
  return ScalarType::Float32;
}

image_files::Pixel pixelOf(ScalarType t) {
  switch (t) {
    case ScalarType::UInt8:
      return image_files::Pixel::UInt8;
    case ScalarType::UInt16:
      return image_files::Pixel::UInt16;
    case ScalarType::Int16:
      return image_files::Pixel::Int16;
    case ScalarType::Float32:
      break;
  }
  return image_files::Pixel::Float32;
}

// Appends subimage `subimage` of `in` to `v` at slice z after checking it matches the first slice.
void readSlice(const image_files::Reader& in, const std::string& file, int subimage, Volume& v,
               int z) {
  image_files::Layout spec;
  if (!in.subimage(subimage, spec))
    throw FormatError(file, "cannot seek to page " + std::to_string(subimage));
  if (spec.channels != 1)
    throw FormatError(file, "has " + std::to_string(spec.channels) +
                                " channels; slices must be single-channel greyscale");
  if (spec.width != v.dims.x || spec.height != v.dims.y || spec.depth > 1)
    throw FormatError(file, "is " + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                                " but the first slice is " + std::to_string(v.dims.x) + "x" +
                                std::to_string(v.dims.y));
  std::byte* dst = v.data.data() + std::size_t(z) * std::size_t(v.dims.x) * std::size_t(v.dims.y) *
                                       scalarBytes(v.type);
  in.readChannel0(subimage, pixelOf(v.type), dst, file);
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

  auto first = std::make_unique<image_files::Reader>(files[0]);
  image_files::Layout spec0, page;
  if (!first->subimage(0, spec0)) throw FormatError(files[0], "holds no image");
  int pages = 1;
  if (files.size() == 1)
    while (first->subimage(pages, page)) ++pages;
  const int depth = files.size() > 1 ? int(files.size()) : pages;
  const glm::ivec3 dims(spec0.width, spec0.height, depth);
  checkDims(dims, path);
  Volume v = Volume::allocate(dims, typeFor(spec0.format));
  if (files.size() > 1) {
    first.reset();
    for (int z = 0; z < depth; ++z) {
      const image_files::Reader in(files[std::size_t(z)]);
      readSlice(in, files[std::size_t(z)], 0, v, z);
    }
  } else {
    for (int z = 0; z < depth; ++z) readSlice(*first, path + " page " + std::to_string(z), z, v, z);
  }
  v.computeRange();
  return v;
}

}  // namespace voxwall::codec
