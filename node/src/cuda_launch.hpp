// The CUDA backend's kernel launch, split by view type like the CPU backend's blocks
// (cpu_blocks.hpp): cuda_backend.cu dispatches on the volume's device view, and each view's
// kernel is compiled by nvcc in a translation unit of its own (CMake writes one per view from
// cuda_view.cu.in), so the build spreads nvcc's work, the longest of the build, over all cores.
// The kernel and its launch stay in the same unit (no relocatable device code needed).
#pragma once

#include <cuda_runtime.h>

#include <cstdint>
#include <variant>
#include <voxwall/node/renderer.hpp>

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

// Launches the raycast kernel over `launch` for `view` (asynchronous; the caller checks
// cudaGetLastError). Defined in cuda_launch_impl.cuh, instantiated once per view type.
template <class View>
void launchRaycast(const View& view, const Launch& launch);

}  // namespace voxwall::node::cuda
