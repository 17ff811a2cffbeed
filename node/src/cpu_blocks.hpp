// The CPU backend's per-tile work, split by view type: cpu_backend.cpp dispatches on the volume's
// view, and the views' raycasters are compiled in several translation units (CMake writes them
// from cpu_view.cpp.in; view_units.hpp says which unit compiles which view), so a build spreads
// the heaviest code over all its cores instead of compiling every view's instantiation in one
// file. Each of those units compiles the packet raycaster once per SIMD instruction set
// (cpu_view_targets.hpp) and picks the best the CPU has when it runs.
#pragma once

#include <cstdint>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>
#include <voxwall/node/page_cache.hpp>
#include <voxwall/node/renderer.hpp>

#include "view_units.hpp"

namespace voxwall::node::cpu {

inline constexpr int kBlockPixels = 16;

// The level of `view` whose full-resolution voxels the packets sample from the backend's decoded
// pages: the view itself, or what its pagedLevel() names (ksvd's level 0).
using pages::pagedLevel;
// Views with such a level (PageableLevel, page_cache.hpp): the brick views (vq, tvq), ksvd, svmm.
template <class V>
inline constexpr bool kPaged =
    PageableLevel<std::remove_cvref_t<decltype(pagedLevel(std::declval<const V&>()))>>;

// Views with coarser levels the pages can hold too (ksvd, svmm): under pressure
// (RenderSettings::lodUnderPressure) the lanes whose full-resolution page is not resident sample
// level 1 (coarsePages(), each voxel coarseScale() voxels of level 0 a side) from pages of its
// own. Call them only where view.levels > 1.
template <class V>
inline constexpr bool kLevels = kPaged<V>&& requires(const V& v) {
  requires PageableLevel<std::remove_cvref_t<decltype(v.coarsePages())>>;
  { v.coarseScale() } -> std::convertible_to<float>;
};
template <class View>
decltype(auto) coarseLevel(const View& view) {
  return view.coarsePages();
}
template <class View>
float coarseScale(const View& view) {
  return view.coarseScale();
}

// One tile's blocks of kBlockPixels x kBlockPixels points, rendered by `threads` threads. Point
// (x, y) of the tile is the ray through virtual-screen pixel (tile.x + x * stride, tile.y + y *
// stride); a ray a pixel at stride 1. With `need`, only the points whose flag is set are traced
// and written (tile.width x tile.height flags, row by row).
struct TileJob {
  const FramePlan& plan;
  const Rect& tile;
  Image& out;
  int blocksX, blocksY, threads;
  std::vector<double>* blockSeconds;        // per block, when the costs are measured (else null)
  bool packets = true;                      // SIMD ray packets where the CPU has them, else one ray
  const std::atomic<bool>* stop = nullptr;  // when it turns true, blocks not begun are skipped
  PageCache* pages = nullptr;               // decoded pages of the view's paged level (packets)
  PageCache* coarsePages = nullptr;         // under pressure: pages of level 1 (kLevels views)
  int stride = 1;
  const std::uint8_t* need = nullptr;
};

// The Readers of the block this thread renders (null: no pages), which the packets' caches take:
// of the paged level and, under pressure, of level 1.
inline thread_local PageCache::Reader* currentReader = nullptr;
inline thread_local PageCache::Reader* currentCoarseReader = nullptr;
struct ReaderScope {
  ReaderScope(PageCache::Reader* reader, PageCache::Reader* coarse)
      : previous(currentReader), previousCoarse(currentCoarseReader) {
    currentReader = reader;
    currentCoarseReader = coarse;
  }
  ~ReaderScope() {
    currentReader = previous;
    currentCoarseReader = previousCoarse;
  }
  ReaderScope(const ReaderScope&) = delete;
  ReaderScope& operator=(const ReaderScope&) = delete;
  PageCache::Reader *previous, *previousCoarse;
};

// Renders every block of `job` from `*view`, the view of index `viewIndex` in ViewVariant, one of
// the views unit `Unit` compiles (view_units.hpp); returns the samples taken. Defined in
// cpu_view_targets.hpp, instantiated once per unit.
template <std::size_t Unit>
std::uint64_t renderUnitBlocks(std::size_t viewIndex, const void* view, const TileJob& job);

// Renders every block of `job` from `view`; returns the samples taken.
template <class View>
std::uint64_t renderBlocks(const View& view, const TileJob& job) {
  return renderUnitBlocks<kViewUnit<View>>(kViewIndex<View>, &view, job);
}

// The rays per packet on this CPU (1: no SIMD instruction set the build has), and its name.
std::size_t packetLanes();
std::string packetTarget();

}  // namespace voxwall::node::cpu
