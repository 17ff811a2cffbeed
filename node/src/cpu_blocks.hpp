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
};

// The Reader of the block this thread renders (null: no pages), which the packets' caches take.
inline thread_local PageCache::Reader* currentReader = nullptr;
struct ReaderScope {
  explicit ReaderScope(PageCache::Reader* reader) : previous(currentReader) {
    currentReader = reader;
  }
  ~ReaderScope() { currentReader = previous; }
  ReaderScope(const ReaderScope&) = delete;
  ReaderScope& operator=(const ReaderScope&) = delete;
  PageCache::Reader* previous;
};

// Renders every block of `job` from `view`; returns the samples taken. Defined in
// cpu_view_targets.hpp, instantiated once per view type.
template <class View>
std::uint64_t renderBlocks(const View& view, const TileJob& job);

// The rays per packet on this CPU (1: no SIMD instruction set the build has), and its name.
std::size_t packetLanes();
std::string packetTarget();

}  // namespace voxwall::node::cpu
