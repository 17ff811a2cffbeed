// The CPU backend: threads over 16x16-pixel blocks of the tile, each pixel by raycastPixel.
// Every pixel is independent of the others, so the image is the same for any thread count.
#include <atomic>
#include <chrono>
#include <voxwall/core/parallel.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::node {
namespace {

constexpr int kBlockPixels = 16;

class CpuBackend final : public Backend {
 public:
  explicit CpuBackend(int threads) : threads_(voxwall::resolveThreads(threads)) {}
  std::string name() const override { return "cpu (" + std::to_string(threads_) + " threads)"; }

  TileStats renderTile(const RenderVolume& volume, const FramePlan& plan, const Rect& tile,
                       Image& out, CostGrid* costs) override {
    if (tile.width <= 0 || tile.height <= 0) throw std::invalid_argument("empty tile");
    const auto start = std::chrono::steady_clock::now();
    out = Image(tile.width, tile.height);
    const int bx = (tile.width + kBlockPixels - 1) / kBlockPixels;
    const int by = (tile.height + kBlockPixels - 1) / kBlockPixels;
    std::atomic<std::uint64_t> samples{0};
    // Each block's time, written by the one thread that renders it; spread into `costs` after.
    std::vector<double> blockSeconds(costs ? std::size_t(bx) * std::size_t(by) : 0);
    const auto lut = plan.lut.view();
    std::visit(
        [&](const auto& view) {
          voxwall::parallelFor(std::size_t(bx) * std::size_t(by), threads_, [&](std::size_t b) {
            const auto blockStart =
                costs ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
            const int x0 = int(b % std::size_t(bx)) * kBlockPixels;
            const int y0 = int(b / std::size_t(bx)) * kBlockPixels;
            const int x1 = std::min(x0 + kBlockPixels, tile.width);
            const int y1 = std::min(y0 + kBlockPixels, tile.height);
            std::uint64_t local = 0;
            for (int y = y0; y < y1; ++y)
              for (int x = x0; x < x1; ++x) {
                const auto px =
                    kernels::raycastPixel(view, plan.ray, lut, plan.skip, tile.x + x, tile.y + y);
                out.at(x, y) = kernels::packRgba8(px.rgba);
                local += px.samples;
              }
            samples.fetch_add(local, std::memory_order_relaxed);
            if (costs)
              blockSeconds[b] =
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - blockStart)
                      .count();
          });
        },
        volume.view());
    if (costs)
      for (std::size_t b = 0; b < blockSeconds.size(); ++b) {
        const int x0 = int(b % std::size_t(bx)) * kBlockPixels;
        const int y0 = int(b / std::size_t(bx)) * kBlockPixels;
        costs->add({tile.x + x0, tile.y + y0, std::min(kBlockPixels, tile.width - x0),
                    std::min(kBlockPixels, tile.height - y0)},
                   blockSeconds[b]);
      }
    TileStats stats;
    stats.samples = samples.load();
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return stats;
  }

 private:
  int threads_;
};

}  // namespace

std::unique_ptr<Backend> makeCpuBackend(int threads) {
  return std::make_unique<CpuBackend>(threads);
}

std::unique_ptr<Backend> makeBackend(BackendKind kind, int threads) {
  if (kind == BackendKind::Cuda) return makeCudaBackend();
  return makeCpuBackend(threads);
}

}  // namespace voxwall::node
