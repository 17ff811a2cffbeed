// The CPU backend's per-tile work, split by view type: cpu_backend.cpp dispatches on the volume's
// view, and each view's raycaster is compiled in a translation unit of its own (CMake writes one
// per view from cpu_view.cpp.in), so a build spreads the heaviest code over all its cores
// instead of compiling every view's instantiation in one file. Each of those units compiles the
// packet raycaster once per SIMD instruction set (cpu_view_targets.hpp) and picks the best the
// CPU has when it runs.
#pragma once

#include <cstdint>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>
#include <voxwall/node/page_cache.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::node::cpu {

inline constexpr int kBlockPixels = 16;

// Views whose full-resolution voxels the packets sample from the backend's decoded pages
// (node/page_cache.hpp) when it has some: the brick views (vq, tvq), ksvd's level 0 and svmm.
template <class V>
inline constexpr bool kKsvd = false;
template <int S>
inline constexpr bool kKsvd<codec::kernels::KsvdView<S>> = true;
template <class V>
inline constexpr bool kPaged =
    kKsvd<V> || codec::kernels::BrickView<V> || std::is_same_v<V, codec::kernels::SvmmView>;
template <class View>
auto& pagedLevel(View& view) {
  if constexpr (kKsvd<std::remove_const_t<View>>)
    return view.level[0];
  else
    return view;
}

// Views with coarser levels (ksvd, svmm): under pressure (RenderSettings::lodUnderPressure) the
// lanes whose full-resolution page is not resident sample level 1 from pages of its own.
template <class V>
inline constexpr bool kLevels = kKsvd<V> || std::is_same_v<V, codec::kernels::SvmmView>;

// svmm's level `T` as PageCache takes a level: its grid's size and voxels (looked up through the
// mip-map, as the view's own samples at that level read them).
struct SvmmLevelPages {
  const codec::kernels::SvmmView* view = nullptr;
  int T = 1;
  int dimX = 1, dimY = 1, dimZ = 1;
  float maxX = 0, maxY = 0, maxZ = 0;
  std::uint64_t cacheId = 0;
  using RayCache = codec::kernels::SvmmView::RayCache;
  float voxel(int x, int y, int z, RayCache& rc) const {
    int stop;
    return view->scalar(view->lookup(x, y, z, T, rc, stop));
  }
};

// Level 1 of a view with levels (call only where view.levels > 1), and how many full-resolution
// voxels one of its voxels spans per side.
template <class View>
decltype(auto) coarseLevel(const View& view) {
  if constexpr (kKsvd<View>) {
    return (view.level[1]);
  } else {
    SvmmLevelPages l;
    l.view = &view;
    const int sh = view.level[1].shift;
    l.dimX = ((view.dimX - 1) >> sh) + 1, l.dimY = ((view.dimY - 1) >> sh) + 1;
    l.dimZ = ((view.dimZ - 1) >> sh) + 1;
    l.maxX = float(l.dimX - 1), l.maxY = float(l.dimY - 1), l.maxZ = float(l.dimZ - 1);
    l.cacheId = view.cacheId;
    return l;
  }
}
template <class View>
float coarseScale(const View& view) {
  if constexpr (kKsvd<View>)
    return 2.0f;
  else
    return float(1 << view.level[1].shift);
}

// One tile's blocks of kBlockPixels x kBlockPixels, rendered by `threads` threads.
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

// Renders every block of `job` from `view`; returns the samples taken. Defined in
// cpu_view_targets.hpp, instantiated once per view type.
template <class View>
std::uint64_t renderBlocks(const View& view, const TileJob& job);

// The rays per packet on this CPU (1: no SIMD instruction set the build has), and its name.
std::size_t packetLanes();
std::string packetTarget();

}  // namespace voxwall::node::cpu
