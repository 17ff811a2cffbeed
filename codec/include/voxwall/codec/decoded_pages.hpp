// Decoded pages of a compressed volume's full-resolution voxels (any CachedBrickView: vq, ksvd's
// full-resolution level, tvq; and svmm's view), host only: the CPU backend's SIMD packets sample
// these instead of decoding bricks per ray, so a compressed volume renders at about the speed of
// raw data (docs/rendering.md).
//
// A page holds 32^3 voxels of the volume plus an apron (one voxel below, two above on every
// axis, clamped at the volume's faces), so a sample's eight corners and the 24 voxels of its cell
// gradient all lie in one page, as they lie in one brick of the raw codec: the packet path reads
// them with the same gathers, after one more gather in the page table. Pages are decoded the
// first time a ray samples them (from any thread), into a pool of at most `budget` bytes; a page
// that finds the pool full is not decoded, and rays there keep decoding bricks through the view's
// own caches (svmm's: its mip-map). Regions the rays skip (empty space) are never decoded. The pool
// is allocated untouched, so only decoded pages become resident.
//
// This is the decoded-brick cache of the GPU renderers behind the codecs (Gobbetti, Iglesias
// Guitian and Marton, "COVRA: a compression-domain output-sensitive volume rendering
// architecture", 2012; Guthe and Goesele, "Variable length coding for GPU-based direct volume
// rendering", 2016), kept per rank on the CPU.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <type_traits>
#include <typeindex>
#include <typeinfo>
#include <voxwall/codec/kernels/cached_brick_view.hpp>

namespace voxwall::codec {

// What a page stores of a level's voxels: the float the view samples (voxel(x, y, z, cache)),
// or for a brick view whose decoder's scalar(v) is float(v) + bias on 16-bit values (vq), the
// decoded values themselves (half the bytes; the packets add the bias).
template <class Level>
struct PageFormat {
  static constexpr bool kValues = false;
  using Stored = float;
  static float bias(const Level&) { return 0.0f; }
};
template <class Decoder>
struct PageFormat<kernels::CachedBrickView<Decoder>> {
  static constexpr bool kValues =
      std::is_same_v<typename Decoder::Value, std::uint16_t> && requires(const Decoder& d) {
    float(d.bias);
  };
  using Stored = std::conditional_t<kValues, std::uint16_t, float>;
  static float bias(const kernels::CachedBrickView<Decoder>& level) {
    if constexpr (kValues)
      return level.decoder.bias;
    else
      return 0.0f;
  }
};

class DecodedPages {
 public:
  static constexpr int kShift = 5;  // 32 voxels per page side
  static constexpr int kSide = 1 << kShift;
  static constexpr int kRow = kSide + 3;  // the apron: one voxel below, two above
  static constexpr int kSlice = kRow * kRow;
  static constexpr int kVoxels = kSlice * kRow;
  // A page's table entry: the element offset of its page in the pool, or one of these.
  static constexpr std::int32_t kAbsent = -1, kFilling = -2, kNoRoom = -3;

  // Pages for `level` (a view with cacheId, dimX..dimZ and voxel(x, y, z, RayCache&): a
  // CachedBrickView, svmm's view), in at most `budgetBytes` of decoded voxels (the pool is further
  // capped where 32-bit element offsets end, just under 2 GiB of 16-bit values).
  template <class Level>
  static std::unique_ptr<DecodedPages> make(const Level& level, std::uint64_t budgetBytes) {
    return std::unique_ptr<DecodedPages>(
        new DecodedPages(typeid(Level), level.cacheId, level.dimX, level.dimY, level.dimZ,
                         sizeof(typename PageFormat<Level>::Stored), budgetBytes));
  }

  // The pool `make` would allocate for `level` with this budget (what becomes resident when rays
  // reach every page).
  template <class Level>
  static std::uint64_t bytesFor(const Level& level, std::uint64_t budgetBytes) {
    const auto valueBytes = sizeof(typename PageFormat<Level>::Stored);
    return capacityFor(level.dimX, level.dimY, level.dimZ, valueBytes, budgetBytes) *
           std::uint64_t(kVoxels) * valueBytes;
  }

  // Whether these are the pages of `level` (its view type, cacheId and size: each codec numbers
  // its volumes from 1).
  template <class Level>
  bool holds(const Level& level) const {
    return std::type_index(typeid(Level)) == type_ && level.cacheId == id_ && level.dimX == dimX &&
           level.dimY == dimY && level.dimZ == dimZ;
  }

  int dimX, dimY, dimZ;
  int pagesX, pagesY, pagesZ;

  // The page table, for gathers: the entry of page (px, py, pz) is at
  // (pz * pagesY + py) * pagesX + px. Entries only ever change from kAbsent to kFilling to an
  // offset (published after the page is written) or kNoRoom.
  const std::int32_t* table() const { return reinterpret_cast<const std::int32_t*>(slot_.get()); }
  // The pool, for gathers (readable 8 bytes past its last element).
  const void* pool() const { return pool_.get(); }
  std::size_t pageBytes() const { return std::size_t(kVoxels) * valueBytes_; }
  std::size_t capacityPages() const { return std::size_t(capacity_); }
  std::size_t decodedPages() const {
    const auto n = std::size_t(used_.load(std::memory_order_relaxed));
    return n < std::size_t(capacity_) ? n : std::size_t(capacity_);
  }
  // Bytes of every page of the volume with its apron (what a big enough budget ends up holding
  // when rays reach every page).
  std::uint64_t allPagesBytes() const {
    return std::uint64_t(pagesX) * std::uint64_t(pagesY) * std::uint64_t(pagesZ) * pageBytes();
  }

  // The table entry of `page` after trying to decode it from `level` (the level the pages were
  // made for): its offset, kNoRoom, or kFilling while another thread decodes it.
  template <class Level>
  std::int32_t fill(std::int32_t page, const Level& level) {
    auto& entry = slot_[std::size_t(page)];
    std::int32_t state = entry.load(std::memory_order_acquire);
    if (state != kAbsent) return state;
    if (!entry.compare_exchange_strong(state, kFilling, std::memory_order_acq_rel)) return state;
    const std::int32_t index = used_.fetch_add(1, std::memory_order_relaxed);
    if (index >= capacity_) {
      entry.store(kNoRoom, std::memory_order_release);
      return kNoRoom;
    }
    using Format = PageFormat<Level>;
    auto* out = reinterpret_cast<typename Format::Stored*>(pool_.get()) +
                std::size_t(index) * std::size_t(kVoxels);
    const int px = page % pagesX, py = (page / pagesX) % pagesY, pz = page / pagesX / pagesY;
    typename Level::RayCache cache;
    for (int z = 0; z < kRow; ++z)
      for (int y = 0; y < kRow; ++y) {
        const int gz = kernels::clampIndex(pz * kSide + z - 1, dimZ);
        const int gy = kernels::clampIndex(py * kSide + y - 1, dimY);
        for (int x = 0; x < kRow; ++x) {
          const int gx = kernels::clampIndex(px * kSide + x - 1, dimX);
          if constexpr (Format::kValues) {
            const auto* b =
                level.brick(Level::brickOf(gx), Level::brickOf(gy), Level::brickOf(gz), cache);
            *out++ = b[Level::within(gx) +
                       Level::kSide * (Level::within(gy) + Level::kSide * Level::within(gz))];
          } else {
            *out++ = level.voxel(gx, gy, gz, cache);
          }
        }
      }
    const std::int32_t offset = index * kVoxels;
    entry.store(offset, std::memory_order_release);
    return offset;
  }

 private:
  DecodedPages(const std::type_info& type, std::uint64_t id, int x, int y, int z,
               std::size_t valueBytes, std::uint64_t budgetBytes)
      : dimX(x), dimY(y), dimZ(z), type_(type), id_(id), valueBytes_(valueBytes) {
    if (x <= 0 || y <= 0 || z <= 0) throw std::invalid_argument("decoded pages of an empty volume");
    pagesX = (x + kSide - 1) / kSide, pagesY = (y + kSide - 1) / kSide;
    pagesZ = (z + kSide - 1) / kSide;
    const std::uint64_t pages =
        std::uint64_t(pagesX) * std::uint64_t(pagesY) * std::uint64_t(pagesZ);
    if (pages >= (std::uint64_t(1) << 31)) throw std::invalid_argument("too many decoded pages");
    const std::uint64_t capacity = capacityFor(x, y, z, valueBytes, budgetBytes);
    capacity_ = std::int32_t(capacity);
    slot_ = std::make_unique<std::atomic<std::int32_t>[]>(std::size_t(pages));
    for (std::uint64_t i = 0; i < pages; ++i) slot_[i].store(kAbsent, std::memory_order_relaxed);
    // Default-initialised: the kernel maps the pool's memory as pages are written.
    pool_.reset(new std::byte[std::size_t(capacity) * pageBytes() + 8]);
  }

  // Pages the pool holds: the budget's worth, at most every page of the volume, and no more than
  // int32 element offsets reach (16-bit gathers address bytes with them).
  static std::uint64_t capacityFor(int x, int y, int z, std::size_t valueBytes,
                                   std::uint64_t budgetBytes) {
    const std::uint64_t pages = std::uint64_t((x + kSide - 1) / kSide) *
                                std::uint64_t((y + kSide - 1) / kSide) *
                                std::uint64_t((z + kSide - 1) / kSide);
    const std::uint64_t maxPages = ((std::uint64_t(1) << 31) - 64) / (std::uint64_t(kVoxels) * 2);
    std::uint64_t capacity = budgetBytes / (std::uint64_t(kVoxels) * valueBytes);
    if (capacity > maxPages) capacity = maxPages;
    return capacity < pages ? capacity : pages;
  }

  static_assert(sizeof(std::atomic<std::int32_t>) == sizeof(std::int32_t) &&
                std::atomic<std::int32_t>::is_always_lock_free);

  std::type_index type_;
  std::uint64_t id_;
  std::size_t valueBytes_;
  std::int32_t capacity_ = 0;
  std::atomic<std::int32_t> used_{0};
  std::unique_ptr<std::atomic<std::int32_t>[]> slot_;
  std::unique_ptr<std::byte[]> pool_;
};

}  // namespace voxwall::codec
