// The volume model every module shares: a dense 3D grid of scalars, x fastest.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace voxwall::codec {

// Scalar types a volume can hold. The values are stored in files: never reuse one.
enum class ScalarType : std::uint32_t {
  UInt8 = 1,
  UInt16 = 2,
  Int16 = 3,
  Float32 = 4,
};

std::size_t scalarBytes(ScalarType type);
std::string_view scalarName(ScalarType type);  // "uint8", "uint16", "int16", "float32"
// Parses a scalarName(); throws std::invalid_argument naming the accepted spellings.
ScalarType parseScalarType(std::string_view name);

// Calls f(T{}) with T the C++ type of `type` (std::uint8_t, std::uint16_t, std::int16_t, float).
template <class F>
decltype(auto) dispatchScalar(ScalarType type, F&& f);

// Where the voxels lie in the patient (or the scanner, or the world). voxwall's one convention is
// DICOM's LPS: patient x grows to the patient's Left, y to Posterior, z to Superior, in
// millimetres. A voxel's centre at index (i, j, k) lies at
//   origin + direction * (spacing * (i, j, k))
// with `direction`'s columns the unit patient directions of the x, y and z index axes. Readers
// convert what their format says (NIfTI's RAS, NRRD's `space`) to it; voxels stay in file order.
struct Orientation {
  glm::dmat3 direction{1.0};  // orthonormal (a rotation, or a rotation and a mirror)
  glm::dvec3 origin{0.0};     // the centre of voxel (0, 0, 0)
  bool operator==(const Orientation&) const = default;
};

// The patient direction each index axis points closest to, one letter per axis from its largest
// component: "LPS" for the identity, "RAS" for diag(-1, -1, 1), "LIP", ... Oblique axes get the
// letter of their largest component (as ITK and nibabel print them).
std::string orientationLetters(const glm::dmat3& direction);
// The direction matrix of three letters naming distinct axes, each of R/L, A/P, S/I (any case),
// e.g. "RAS"; throws std::invalid_argument naming the accepted letters.
glm::dmat3 parseOrientationLetters(std::string_view letters);
// Empty when `direction` is finite, its columns unit length and orthogonal (within 1e-4);
// otherwise what is wrong with it, for an error message.
std::string orientationProblem(const glm::dmat3& direction);
// The nearest rotation-or-mirror to `m`'s columns (Gram-Schmidt in x, y, z order), for a matrix
// with shear or unequal column lengths; the spacing is the columns' lengths.
glm::dmat3 orthonormalized(const glm::dmat3& m);

// A dense volume. dims in voxels, spacing in world units (millimetres for medical data) per
// voxel, data holds dims.x*dims.y*dims.z scalars of `type`, x fastest, native (little) endian.
// valueMin/valueMax are the range of the stored values (computeRange() fills them);
// `orientation` places the voxels in the patient (identity: x, y, z are L, P, S).
struct Volume {
  glm::ivec3 dims{0, 0, 0};
  glm::dvec3 spacing{1.0, 1.0, 1.0};
  Orientation orientation{};
  ScalarType type = ScalarType::UInt8;
  double valueMin = 0.0;
  double valueMax = 0.0;
  std::vector<std::byte> data;

  // Allocates zeroed storage; throws std::invalid_argument for non-positive dims.
  static Volume allocate(glm::ivec3 dims, ScalarType type, glm::dvec3 spacing = {1, 1, 1});

  std::size_t voxelCount() const {
    return std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z);
  }
  std::size_t index(int x, int y, int z) const {
    return (std::size_t(z) * std::size_t(dims.y) + std::size_t(y)) * std::size_t(dims.x) +
           std::size_t(x);
  }
  template <class T>
  std::span<T> as() {
    return {reinterpret_cast<T*>(data.data()), voxelCount()};
  }
  template <class T>
  std::span<const T> as() const {
    return {reinterpret_cast<const T*>(data.data()), voxelCount()};
  }
  // Value of one voxel converted to double (slow path, for tests and metrics).
  double valueAt(std::size_t i) const;
  // Scans the data and sets valueMin/valueMax.
  void computeRange();
};

// Largest volume we accept from any reader: 2^34 voxels (16 Gi), so a corrupt header cannot
// make us allocate without bound.
inline constexpr std::size_t kMaxVoxels = std::size_t(1) << 34;
// Checks dims are positive and their product below kMaxVoxels; throws FormatError naming `file`.
void checkDims(glm::ivec3 dims, const std::string& file);

template <class F>
decltype(auto) dispatchScalar(ScalarType type, F&& f) {
  switch (type) {
    case ScalarType::UInt8:
      return f(std::uint8_t{});
    case ScalarType::UInt16:
      return f(std::uint16_t{});
    case ScalarType::Int16:
      return f(std::int16_t{});
    case ScalarType::Float32:
      return f(float{});
  }
  throw std::invalid_argument("unknown scalar type");
}

}  // namespace voxwall::codec
