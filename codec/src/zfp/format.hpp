// What the zfp codec's encoder and reader share (private to src/zfp/): the bricks' shapes, the
// parameters of each mode, and one brick's stream through libzfp.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <glm/vec3.hpp>
#include <vector>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/zfp_codec.hpp>

namespace voxwall::codec::zfp {

inline constexpr int kBrick = kernels::kZfpBrick;
inline constexpr int kBrickVoxels = kBrick * kBrick * kBrick;
inline constexpr std::size_t kParamsBytes = 72;

// The voxels of brick (bx, by, bz) inside a volume of `dims` (16 per axis but at the far faces).
struct BrickShape {
  int nx = kBrick, ny = kBrick, nz = kBrick;
  int voxels() const { return nx * ny * nz; }
  int blocks() const { return ((nx + 3) / 4) * ((ny + 3) / 4) * ((nz + 3) / 4); }
};
BrickShape brickShape(glm::ivec3 dims, std::uint64_t brick);
glm::ivec3 brickGrid(glm::ivec3 dims);

// zfp's expert parameters of a mode: `setting` is the tolerance, precision or rate (unused for
// reversible). Throws std::invalid_argument when zfp refuses them.
kernels::ZfpStreamParams streamParams(Mode mode, double setting);
// The mode zfp sees in `params` (Mode{0} when it sees none): what a reader checks.
Mode modeOf(const kernels::ZfpStreamParams& params);

// The most bytes zfp reads for a brick of `shape` under `params` (every block at its bit budget,
// plus the words the bit reader fetches ahead).
std::size_t maxStreamBytes(const kernels::ZfpStreamParams& params, const BrickShape& shape);

// Compresses the brick's voxels (in[x + 16 (y + 16 z)]) and appends the stream (a multiple of 8
// bytes) to `out`; returns its length.
std::size_t compressBrick(const kernels::ZfpStreamParams& params, const float* in,
                          const BrickShape& shape, std::vector<std::uint8_t>& out);
// Decompresses `bytes` bytes of a brick's stream into out[x + 16 (y + 16 z)] (other entries are
// left alone). Reads no byte past data + bytes, whatever the bytes hold.
void decompressBrick(const kernels::ZfpStreamParams& params, const std::uint8_t* data,
                     std::size_t bytes, const BrickShape& shape, float* out);

// The bytes of a stored brick: its voxels in `type`, padded to 8 bytes.
inline std::size_t storedBytes(ScalarType type, const BrickShape& shape) {
  return (std::size_t(shape.voxels()) * scalarBytes(type) + 7) / 8 * 8;
}

// A decoded value as the reader gives it: clamped to [lo, hi] (NaN to lo), rounded for integer
// types.
inline float finish(float v, float lo, float hi, bool integer) {
  if (!(v >= lo)) v = lo;
  if (v > hi) v = hi;
  if (integer) v = std::nearbyint(v);
  return v;
}

}  // namespace voxwall::codec::zfp
