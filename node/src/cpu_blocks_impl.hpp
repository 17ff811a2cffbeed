// The block loop of the CPU backend, over pixels one ray at a time (the scalar path) or over
// packets of rays; included by cpu_view_targets.hpp only.
#pragma once

#include <atomic>
#include <chrono>
#include <voxwall/core/parallel.hpp>

#include "cpu_blocks.hpp"

namespace voxwall::node::cpu {

// Runs trace(x0, y0, x1, y1, samples) over every block of the tile (tile-local pixel bounds),
// timing each block when the job measures costs; returns the samples taken.
template <class Trace>
std::uint64_t forEachBlock(const TileJob& job, const Trace& trace) {
  std::atomic<std::uint64_t> samples{0};
  const auto& tile = job.tile;
  voxwall::parallelFor(
      std::size_t(job.blocksX) * std::size_t(job.blocksY), job.threads, [&](std::size_t b) {
        if (job.stop && job.stop->load(std::memory_order_relaxed)) return;
        const auto blockStart = job.blockSeconds ? std::chrono::steady_clock::now()
                                                 : std::chrono::steady_clock::time_point{};
        const int x0 = int(b % std::size_t(job.blocksX)) * kBlockPixels;
        const int y0 = int(b / std::size_t(job.blocksX)) * kBlockPixels;
        const int x1 = std::min(x0 + kBlockPixels, tile.width);
        const int y1 = std::min(y0 + kBlockPixels, tile.height);
        std::uint64_t local = 0;
        trace(x0, y0, x1, y1, local);
        samples.fetch_add(local, std::memory_order_relaxed);
        if (job.blockSeconds)
          (*job.blockSeconds)[b] =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - blockStart).count();
      });
  return samples.load();
}

// One ray per pixel (raycastPixel, the code CUDA runs per thread).
template <class View>
std::uint64_t renderScalarBlocks(const View& view, const TileJob& job) {
  const auto lut = job.plan.lut.view();
  return forEachBlock(job, [&](int x0, int y0, int x1, int y1, std::uint64_t& samples) {
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        if (job.need && !job.need[std::size_t(y) * std::size_t(job.tile.width) + std::size_t(x)])
          continue;
        const auto px =
            kernels::raycastPixel(view, job.plan.ray, lut, job.plan.skip,
                                  job.tile.x + x * job.stride, job.tile.y + y * job.stride);
        job.out.at(x, y) = kernels::packRgba8(px.rgba);
        samples += px.samples;
      }
  });
}

}  // namespace voxwall::node::cpu
