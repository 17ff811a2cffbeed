// The CPU backend's per-tile work, split by view type: cpu_backend.cpp dispatches on the volume's
// view, and each view's raycaster is compiled in a translation unit of its own (CMake writes one
// per view from cpu_view.cpp.in), so a build spreads the heaviest code over all its cores
// instead of compiling every view's instantiation in one file.
#pragma once

#include <cstdint>
#include <variant>
#include <vector>
#include <voxwall/node/renderer.hpp>

namespace voxwall::node::cpu {

inline constexpr int kBlockPixels = 16;

// One tile's blocks of kBlockPixels x kBlockPixels, rendered by `threads` threads.
struct TileJob {
  const FramePlan& plan;
  const Rect& tile;
  Image& out;
  int blocksX, blocksY, threads;
  std::vector<double>* blockSeconds;  // per block, when the costs are measured (else null)
};

// Renders every block of `job` from `view`; returns the samples taken. Defined in
// cpu_blocks_impl.hpp, instantiated once per view type.
template <class View>
std::uint64_t renderBlocks(const View& view, const TileJob& job);

}  // namespace voxwall::node::cpu
