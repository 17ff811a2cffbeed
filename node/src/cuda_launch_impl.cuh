// The definition of cuda::launchUnit (cuda_launch.hpp), included by the units only.
#pragma once

#include "cuda_launch.hpp"

namespace voxwall::node::cuda {

template <class View>
__global__ void raycastKernel(View view, kernels::RayFrame frame, kernels::TransferLut lut,
                              kernels::SkipGrid skip, int tileX, int tileY, int tileW, int tileH,
                              std::uint32_t* out, unsigned long long* samples) {
  const int x = int(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = int(blockIdx.y * blockDim.y + threadIdx.y);
  unsigned count = 0;
  if (x < tileW && y < tileH) {
    const auto r = kernels::raycastPixel(view, frame, lut, skip, tileX + x, tileY + y);
    out[std::size_t(y) * std::size_t(tileW) + std::size_t(x)] = kernels::packRgba8(r.rgba);
    count = r.samples;
  }
  // One atomic per warp instead of one per pixel.
  count = __reduce_add_sync(0xffffffffu, count);
  if ((threadIdx.x + threadIdx.y * blockDim.x) % 32 == 0)
    atomicAdd(samples, (unsigned long long)count);
}

template <class View>
void launchView(const View& view, const Launch& a) {
  raycastKernel<<<a.grid, a.block>>>(view, a.frame, a.lut, a.skip, a.tileX, a.tileY, a.tileW,
                                     a.tileH, a.out, a.samples);
}

template <std::size_t Unit>
void launchUnit(std::size_t viewIndex, const void* view, const Launch& launch) {
  forEachViewOfUnit<Unit>([&](auto index) {
    using View = std::variant_alternative_t<decltype(index)::value, ViewVariant>;
    if (viewIndex == index) launchView(*static_cast<const View*>(view), launch);
  });
}

}  // namespace voxwall::node::cuda
