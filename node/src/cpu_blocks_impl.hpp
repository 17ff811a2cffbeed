// The definition of cpu::renderBlocks (cpu_blocks.hpp), included by the per-view translation
// units only.
#pragma once

#include <atomic>
#include <chrono>
#include <voxwall/core/parallel.hpp>

#include "cpu_blocks.hpp"

namespace voxwall::node::cpu {

template <class View>
std::uint64_t renderBlocks(const View& view, const TileJob& job) {
  std::atomic<std::uint64_t> samples{0};
  const auto lut = job.plan.lut.view();
  const auto& tile = job.tile;
  voxwall::parallelFor(
      std::size_t(job.blocksX) * std::size_t(job.blocksY), job.threads, [&](std::size_t b) {
        const auto blockStart = job.blockSeconds ? std::chrono::steady_clock::now()
                                                 : std::chrono::steady_clock::time_point{};
        const int x0 = int(b % std::size_t(job.blocksX)) * kBlockPixels;
        const int y0 = int(b / std::size_t(job.blocksX)) * kBlockPixels;
        const int x1 = std::min(x0 + kBlockPixels, tile.width);
        const int y1 = std::min(y0 + kBlockPixels, tile.height);
        std::uint64_t local = 0;
        for (int y = y0; y < y1; ++y)
          for (int x = x0; x < x1; ++x) {
            const auto px = kernels::raycastPixel(view, job.plan.ray, lut, job.plan.skip,
                                                  tile.x + x, tile.y + y);
            job.out.at(x, y) = kernels::packRgba8(px.rgba);
            local += px.samples;
          }
        samples.fetch_add(local, std::memory_order_relaxed);
        if (job.blockSeconds)
          (*job.blockSeconds)[b] =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - blockStart).count();
      });
  return samples.load();
}

}  // namespace voxwall::node::cpu
