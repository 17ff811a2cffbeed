// The CUDA backend's kernel launch, split by view type like the CPU backend's blocks
// (cpu_blocks.hpp): cuda_backend.cu dispatches on the volume's device view, and the views'
// kernels are compiled by nvcc in several translation units (CMake writes them from
// cuda_view.cu.in; view_units.hpp says which unit compiles which view), so the build spreads
// nvcc's work, the longest of the build, over all cores.
// The kernel and its launch stay in the same unit (no relocatable device code needed).
#pragma once

#include <cuda_runtime.h>

#include <cstdint>
#include <variant>
#include <voxwall/node/renderer.hpp>

#include "view_units.hpp"

namespace voxwall::node::cuda {

// One tile: the launch shape and the kernel's arguments.
struct Launch {
  dim3 grid, block;
  kernels::RayFrame frame;
  kernels::TransferLut lut;
  kernels::SkipGrid skip;
  int tileX = 0, tileY = 0, tileW = 0, tileH = 0;
  std::uint32_t* out = nullptr;           // device, tileW x tileH
  unsigned long long* samples = nullptr;  // device, one counter
};

// Launches the raycast kernel over `launch` for `*view`, the view of index `viewIndex` in
// ViewVariant, one of those unit `Unit` compiles. Defined in cuda_launch_impl.cuh, instantiated
// once per unit (cuda_view.cu.in).
template <std::size_t Unit>
void launchUnit(std::size_t viewIndex, const void* view, const Launch& launch);

// Launches the raycast kernel over `launch` for `view` (asynchronous; the caller checks
// cudaGetLastError).
template <class View>
void launchRaycast(const View& view, const Launch& launch) {
  launchUnit<kViewUnit<View>>(kViewIndex<View>, &view, launch);
}

}  // namespace voxwall::node::cuda
