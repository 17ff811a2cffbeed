#include <algorithm>
#include <cctype>
#include <cmath>
#include <glm/geometric.hpp>
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

std::string orientationLetters(const glm::dmat3& direction) {
  // Index 0 of each pair is the positive LPS direction.
  static constexpr char kLetters[3][2] = {{'L', 'R'}, {'P', 'A'}, {'S', 'I'}};
  std::string out;
  for (int c = 0; c < 3; ++c) {
    const glm::dvec3 col = direction[c];
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (std::abs(col[a]) > std::abs(col[axis])) axis = a;
    out += kLetters[axis][col[axis] < 0 ? 1 : 0];
  }
  return out;
}

glm::dmat3 parseOrientationLetters(std::string_view letters) {
  const auto fail = [&] {
    return std::invalid_argument(
        "orientation '" + std::string(letters) +
        "' is not three letters naming the patient direction of the x, y and z axes, one of R/L, "
        "one of A/P and one of S/I (e.g. RAS, LPS, LAS)");
  };
  if (letters.size() != 3) throw fail();
  glm::dmat3 m(0.0);
  bool used[3] = {false, false, false};
  for (int c = 0; c < 3; ++c) {
    int axis = 0;
    double sign = 1;
    switch (std::toupper(static_cast<unsigned char>(letters[c]))) {
      case 'L':
        axis = 0, sign = 1;
        break;
      case 'R':
        axis = 0, sign = -1;
        break;
      case 'P':
        axis = 1, sign = 1;
        break;
      case 'A':
        axis = 1, sign = -1;
        break;
      case 'S':
        axis = 2, sign = 1;
        break;
      case 'I':
        axis = 2, sign = -1;
        break;
      default:
        throw fail();
    }
    if (used[axis]) throw fail();
    used[axis] = true;
    m[c][axis] = sign;
  }
  return m;
}

std::string orientationProblem(const glm::dmat3& direction) {
  static constexpr double kTolerance = 1e-4;
  for (int c = 0; c < 3; ++c) {
    const glm::dvec3 col = direction[c];
    if (!std::isfinite(col.x) || !std::isfinite(col.y) || !std::isfinite(col.z))
      return "its direction matrix is not finite";
    if (std::abs(glm::length(col) - 1.0) > kTolerance)
      return "its direction for axis " + std::string(1, "xyz"[c]) + " is not unit length";
  }
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      if (std::abs(glm::dot(direction[a], direction[b])) > kTolerance)
        return std::string("its directions for axes ") + "xyz"[a] + " and " + "xyz"[b] +
               " are not orthogonal (a sheared grid)";
  return {};
}

glm::dmat3 orthonormalized(const glm::dmat3& m) {
  glm::dmat3 out(1.0);
  for (int c = 0; c < 3; ++c) {
    glm::dvec3 v = m[c];
    for (int p = 0; p < c; ++p) v -= glm::dot(v, out[p]) * out[p];
    const double len = glm::length(v);
    if (!(len > 1e-12) || !std::isfinite(len)) return glm::dmat3(1.0);
    out[c] = v / len;
  }
  return out;
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
