#include <algorithm>
#include <limits>
#include <stdexcept>
#include <voxwall/codec/volume.hpp>
#include <voxwall/core/errors.hpp>

namespace voxwall::codec {

std::size_t scalarBytes(ScalarType type) {
  return dispatchScalar(type, [](auto t) { return sizeof(t); });
}

std::string_view scalarName(ScalarType type) {
  switch (type) {
    case ScalarType::UInt8:
      return "uint8";
    case ScalarType::UInt16:
      return "uint16";
    case ScalarType::Int16:
      return "int16";
    case ScalarType::Float32:
      return "float32";
  }
  return "unknown";
}

ScalarType parseScalarType(std::string_view name) {
  for (auto t : {ScalarType::UInt8, ScalarType::UInt16, ScalarType::Int16, ScalarType::Float32})
    if (scalarName(t) == name) return t;
  throw std::invalid_argument("unknown scalar type '" + std::string(name) +
                              "' (expected uint8, uint16, int16 or float32)");
}

void checkDims(glm::ivec3 dims, const std::string& file) {
  if (dims.x <= 0 || dims.y <= 0 || dims.z <= 0)
    throw FormatError(file, "invalid dimensions " + std::to_string(dims.x) + "x" +
                                std::to_string(dims.y) + "x" + std::to_string(dims.z));
  const double voxels = double(dims.x) * double(dims.y) * double(dims.z);
  if (voxels > double(kMaxVoxels))
    throw FormatError(file, "dimensions " + std::to_string(dims.x) + "x" + std::to_string(dims.y) +
                                "x" + std::to_string(dims.z) + " exceed the limit of " +
                                std::to_string(kMaxVoxels) + " voxels");
}

Volume Volume::allocate(glm::ivec3 dims, ScalarType type, glm::dvec3 spacing) {
  if (dims.x <= 0 || dims.y <= 0 || dims.z <= 0)
    throw std::invalid_argument("volume dimensions must be positive");
  Volume v;
  v.dims = dims;
  v.type = type;
  v.spacing = spacing;
  v.data.resize(v.voxelCount() * scalarBytes(type));
  return v;
}

double Volume::valueAt(std::size_t i) const {
  return dispatchScalar(type, [&](auto t) { return double(as<decltype(t)>()[i]); });
}

void Volume::computeRange() {
  dispatchScalar(type, [&](auto t) {
    using T = decltype(t);
    auto values = as<T>();
    if (values.empty()) {
      valueMin = valueMax = 0;
      return;
    }
    auto [lo, hi] = std::minmax_element(values.begin(), values.end());
    valueMin = double(*lo);
    valueMax = double(*hi);
  });
}

}  // namespace voxwall::codec
