// Whole-brick decompression on the host (the reference for the device kernel in device.cu) and
// the stand-in for the device path in builds without CUDA.
#include "bricks.hpp"

#include <stdexcept>
#include <voxwall/codec/ksvd_device.hpp>

namespace voxwall::codec::ksvd {

void checkBrick(const Layout& layout, const BrickRef& b) {
  if (b.level < 0 || b.level >= layout.levels())
    throw std::invalid_argument("ksvd brick: level " + std::to_string(b.level) + " of " +
                                std::to_string(layout.levels()));
  const glm::ivec3 grid = layout.levelBricks(b.level);
  if (b.brick.x < 0 || b.brick.y < 0 || b.brick.z < 0 || b.brick.x >= grid.x ||
      b.brick.y >= grid.y || b.brick.z >= grid.z)
    throw std::invalid_argument("ksvd brick: outside level " + std::to_string(b.level) +
                                "'s grid of bricks");
}

std::vector<float> decompressBricks(const Layout& layout, std::span<const BrickRef> bricks) {
  for (const BrickRef& b : bricks) checkBrick(layout, b);
  return layout.withView([&](const auto& view) {
    constexpr int M = std::decay_t<decltype(view)>::Level::kSide;
    const int n = blocksPerBrick(M), side = n * M;
    const std::size_t brickVoxels = std::size_t(side) * std::size_t(side) * std::size_t(side);
    std::vector<float> out(bricks.size() * brickVoxels, 0.0f);
    float block[M * M * M];
    for (std::size_t i = 0; i < bricks.size(); ++i) {
      const auto& level = view.level[bricks[i].level];
      const glm::ivec3 blocks = (layout.levelDims(bricks[i].level) + M - 1) / M;
      float* brick = out.data() + i * brickVoxels;
      for (int j = 0; j < n * n * n; ++j) {
        const glm::ivec3 local{j % n, (j / n) % n, j / (n * n)};
        const glm::ivec3 b = bricks[i].brick * n + local;
        if (b.x >= blocks.x || b.y >= blocks.y || b.z >= blocks.z) continue;
        level.decoder.decode(level.decoder.key(b.x, b.y, b.z), block);
        const glm::ivec3 dims = layout.levelDims(bricks[i].level);
        for (int z = 0, v = 0; z < M; ++z)
          for (int y = 0; y < M; ++y)
            for (int x = 0; x < M; ++x, ++v) {
              if (b.x * M + x >= dims.x || b.y * M + y >= dims.y || b.z * M + z >= dims.z)
                continue;  // the encoder's padding
              brick[(std::size_t(local.z * M + z) * std::size_t(side) +
                     std::size_t(local.y * M + y)) *
                        std::size_t(side) +
                    std::size_t(local.x * M + x)] = block[v];
            }
      }
    }
    return out;
  });
}

#if !defined(VOXWALL_CODEC_CUDA)
bool deviceDecompressionAvailable(std::string* reason) {
  if (reason) *reason = "this build has no CUDA (configured with VOXWALL_CUDA=OFF)";
  return false;
}

std::vector<float> decompressBricksOnDevice(const Layout&, std::span<const BrickRef>) {
  throw std::runtime_error("this build has no CUDA (configured with VOXWALL_CUDA=OFF)");
}
#endif

}  // namespace voxwall::codec::ksvd
