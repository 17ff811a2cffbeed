// The CPU backend: threads over 16x16-pixel blocks of the tile, each block in SIMD packets of
// rays (raycastLanes over Highway vectors) or, without packets, each pixel by raycastPixel. Every
// pixel is independent of the others, so the image is the same for any thread count.
#include <algorithm>
#include <chrono>
#include <voxwall/core/parallel.hpp>
#include <voxwall/node/page_cache.hpp>
#include <voxwall/node/renderer.hpp>

#include "cpu_blocks.hpp"

namespace voxwall::node {
namespace {

using cpu::kBlockPixels;

class CpuBackend final : public Backend {
 public:
  CpuBackend(int threads, bool packets, std::uint64_t decodeCacheBytes)
      : threads_(voxwall::resolveThreads(threads)),
        packets_(packets && cpu::packetLanes() > 1),
        decodeCacheBytes_(decodeCacheBytes) {}
  std::string name() const override {
    return "cpu (" + std::to_string(threads_) + " threads, " +
           (packets_ ? cpu::packetTarget() + " packets of " + std::to_string(cpu::packetLanes()) +
                           " rays"
                     : std::string("one ray at a time")) +
           ")";
  }

  bool tracesLattices() const override { return true; }
  int hostThreads() const override { return threads_; }

  TileStats renderPoints(const RenderVolume& volume, const FramePlan& plan, const RayPoints& points,
                         Image& out, CostGrid* costs, const std::atomic<bool>* stop) override {
    if (points.points.width <= 0 || points.points.height <= 0 || points.stride < 1)
      throw std::invalid_argument("empty lattice");
    if (out.width != points.points.width || out.height != points.points.height)
      throw std::invalid_argument("lattice image of another size");
    return trace(volume, plan, points, out, costs, stop);
  }

  TileStats renderTile(const RenderVolume& volume, const FramePlan& plan, const Rect& tile,
                       Image& out, CostGrid* costs, const std::atomic<bool>* stop) override {
    if (tile.width <= 0 || tile.height <= 0) throw std::invalid_argument("empty tile");
    out = Image(tile.width, tile.height);
    return trace(volume, plan, RayPoints{tile, 1, nullptr}, out, costs, stop);
  }

 private:
  TileStats trace(const RenderVolume& volume, const FramePlan& plan, const RayPoints& points,
                  Image& out, CostGrid* costs, const std::atomic<bool>* stop) {
    const Rect& tile = points.points;
    const int stride = points.stride;
    const auto start = std::chrono::steady_clock::now();
    const int bx = (tile.width + kBlockPixels - 1) / kBlockPixels;
    const int by = (tile.height + kBlockPixels - 1) / kBlockPixels;
    // Each block's time, written by the one thread that renders it; spread into `costs` after.
    std::vector<double> blockSeconds(costs ? std::size_t(bx) * std::size_t(by) : 0);
    cpu::TileJob job{plan,     tile, out, bx, by, threads_, costs ? &blockSeconds : nullptr,
                     packets_, stop};
    job.stride = stride;
    job.need = points.need;
    PageCache::Counts before;  // of the pages this tile uses, once attached
    const std::uint64_t samples = std::visit(
        [&](auto view) {
          if constexpr (cpu::kPaged<decltype(view)>) {
            job.pages = attachPages(cpu::pagedLevel(view), volume.info().type);
            if (job.pages) {
              before = job.pages->counts();
              job.pages->setPressure(plan.lodUnderPressure);
              job.pages->setEvicting(!plan.decodeAhead);
            }
            if constexpr (cpu::kLevels<decltype(view)>)
              if (job.pages && plan.lodUnderPressure && view.levels > 1)
                job.coarsePages = attachCoarsePages(cpu::coarseLevel(view), volume.info().type);
            const std::uint64_t n = cpu::renderBlocks(view, job);
            // The pages lanes sampled coarser for: decoded now, for the frames that follow.
            if (job.pages && plan.lodUnderPressure)
              job.pages->refill(cpu::pagedLevel(view), threads_);
            return n;
          }
          return cpu::renderBlocks(view, job);
        },
        volume.view());
    if (costs)
      for (std::size_t b = 0; b < blockSeconds.size(); ++b) {
        const int x0 = int(b % std::size_t(bx)) * kBlockPixels;
        const int y0 = int(b / std::size_t(bx)) * kBlockPixels;
        costs->add({tile.x + x0 * stride, tile.y + y0 * stride,
                    std::min(kBlockPixels, tile.width - x0) * stride,
                    std::min(kBlockPixels, tile.height - y0) * stride},
                   blockSeconds[b]);
      }
    TileStats stats;
    stats.samples = samples;
    stats.rays = std::uint64_t(tile.area());
    if (points.need)
      stats.rays = std::uint64_t(
          std::count_if(points.need, points.need + tile.area(), [](std::uint8_t f) { return f; }));
    stats.stopped = stop && stop->load();
    if (job.pages) {
      const PageCache::Counts after = job.pages->counts();
      stats.pageHits = after.hits - before.hits;
      stats.pageMissed = after.missed - before.missed;
      stats.pageDecoded = after.misses + after.scratch - before.misses - before.scratch;
      stats.pageEvictions = after.evictions - before.evictions;
      stats.pageCoarse = after.coarse - before.coarse;
      stats.pageWaited = after.waited - before.waited;
      stats.pageScratch = after.scratch - before.scratch;
      stats.pageResidentBytes = job.pages->residentBytes();
      if (job.coarsePages) stats.pageResidentBytes += job.coarsePages->residentBytes();
    }
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return stats;
  }

 public:
  DecodeCacheUse decodeCacheUse() const {
    if (!pages_) return {};
    DecodeCacheUse use;
    use.bytes = pages_->residentBytes();
    use.allPagesBytes = pages_->allPagesBytes();
    use.capacityBytes = std::uint64_t(pages_->capacityPages()) * pages_->pageBytes() +
                        (pages_->memo() ? pages_->memo()->capacityBytes() : 0);
    use.pageBytes = pages_->pageBytes();
    const PageCache::Counts c = pages_->counts();
    use.hits = c.hits, use.missed = c.missed, use.misses = c.misses, use.scratch = c.scratch,
    use.evictions = c.evictions, use.coarse = c.coarse;
    if (coarsePages_) use.coarseBytes = coarsePages_->residentBytes();
    return use;
  }

 private:
  // The pages the packets sample for a brick-coded level: the same ones frame after frame while
  // the volume stays (renderTile runs on one thread at a time; its workers fill pages).
  template <class Level>
  PageCache* attachPages(const Level& level, codec::ScalarType type) {
    // (A budget under one page holds none: no pages.)
    if (!packets_ || PageCache::bytesFor(level, type, decodeCacheBytes_) == 0) return nullptr;
    if (!pages_ || !pages_->holds(level, type, threads_)) {
      pages_.reset();  // the old pool goes before the new one is allocated
      pages_ = PageCache::make(level, type, decodeCacheBytes_, threads_);
    }
    return pages_.get();
  }
  // Under pressure, pages of level 1 of a view with levels, in a quarter of the budget more.
  template <class Level>
  PageCache* attachCoarsePages(const Level& level, codec::ScalarType type) {
    const std::uint64_t budget = decodeCacheBytes_ / 4;
    if (PageCache::bytesFor(level, type, budget) == 0) return nullptr;
    if (!coarsePages_ || !coarsePages_->holds(level, type, threads_)) {
      coarsePages_.reset();
      coarsePages_ = PageCache::make(level, type, budget, threads_);
    }
    return coarsePages_.get();
  }

  int threads_;
  bool packets_;
  std::uint64_t decodeCacheBytes_;
  std::unique_ptr<PageCache> pages_;
  std::unique_ptr<PageCache> coarsePages_;
};

}  // namespace

std::unique_ptr<Backend> makeCpuBackend(int threads, bool packets, std::uint64_t decodeCacheBytes) {
  return std::make_unique<CpuBackend>(threads, packets, decodeCacheBytes);
}

std::uint64_t cpuDecodeCacheNeed(const RenderVolume& volume, std::uint64_t decodeCacheBytes) {
  if (decodeCacheBytes == 0 || cpu::packetLanes() <= 1) return 0;
  return std::visit(
      [&](auto view) -> std::uint64_t {
        if constexpr (cpu::kPaged<decltype(view)>) {
          return PageCache::bytesFor(cpu::pagedLevel(view), volume.info().type, decodeCacheBytes);
        } else {
          return 0;
        }
      },
      volume.view());
}

std::uint64_t cpuCoarsePageNeed(const RenderVolume& volume, std::uint64_t decodeCacheBytes) {
  if (decodeCacheBytes == 0 || cpu::packetLanes() <= 1) return 0;
  return std::visit(
      [&](auto view) -> std::uint64_t {
        if constexpr (cpu::kLevels<decltype(view)>) {
          if (view.levels > 1)
            return PageCache::bytesFor(cpu::coarseLevel(view), volume.info().type,
                                       decodeCacheBytes / 4);
        }
        return 0;
      },
      volume.view());
}

DecodeCacheUse cpuDecodeCacheUse(const Backend& backend) {
  const auto* cpu = dynamic_cast<const CpuBackend*>(&backend);
  return cpu ? cpu->decodeCacheUse() : DecodeCacheUse{};
}

std::size_t cpuPacketLanes() { return cpu::packetLanes(); }

std::unique_ptr<Backend> makeBackend(BackendKind kind, int threads, DeviceDecode decode) {
  if (kind == BackendKind::Cuda) return makeCudaBackend(decode);
  return makeCpuBackend(threads);
}

}  // namespace voxwall::node
