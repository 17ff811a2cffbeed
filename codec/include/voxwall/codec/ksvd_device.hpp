// Decompressing whole bricks of a ksvd volume, on the host and on a CUDA device. The device path
// is COVRA's brick decompressor (Gobbetti, Iglesias Guitian and Marton, 2012, section 5.2): a
// two-phase kernel, one CUDA block per K-SVD block; in phase 1 the block's threads move its
// (atom, coefficient) pairs to shared memory, and after a barrier, in phase 2, each thread sums
// coefficient x atom value for its voxels of the block. The paper decompresses the bricks of the
// view's working set this way into a cache before raycasting them; voxwall's CUDA raycaster
// decodes blocks per ray instead (ksvd_view.hpp), so this is the building block for such a
// cache, tested against the host decoder where a device is present.
#pragma once

#include <glm/vec3.hpp>
#include <span>
#include <string>
#include <vector>
#include <voxwall/codec/ksvd_codec.hpp>

namespace voxwall::codec::ksvd {

// A brick to decompress: its level and its coordinates in that level's grid of bricks.
struct BrickRef {
  int level = 0;
  glm::ivec3 brick{0};
};

// The bricks' voxels, (N M)^3 floats per brick (N M voxels a side, x fastest), one brick after
// the other; voxels past the level's edge (the encoder's padding) are 0. Throws
// std::invalid_argument for a brick outside its level or a level the file does not have.
std::vector<float> decompressBricks(const Layout& layout, std::span<const BrickRef> bricks);

// Whether decompressBricksOnDevice can run here (a CUDA build with a usable device); `reason`
// (if given) says why not.
bool deviceDecompressionAvailable(std::string* reason = nullptr);

// decompressBricks on the first CUDA device, by the two-phase kernel. Throws std::runtime_error
// naming the CUDA error (and in builds or on machines without a device).
std::vector<float> decompressBricksOnDevice(const Layout& layout, std::span<const BrickRef> bricks);

}  // namespace voxwall::codec::ksvd
