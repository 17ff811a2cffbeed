// The CPU backend's cache of decoded pages of a compressed volume's full-resolution voxels (any
// brick view: vq, ksvd's full-resolution level, tvq, zfp; and svmm's view), host only: the SIMD
// packets sample these instead of decoding bricks per ray, so a compressed volume renders at about
// the speed of raw data (docs/rendering.md).
//
// A page holds 32^3 voxels of the volume plus an apron (one voxel below, two above on every
// axis, clamped at the volume's faces), so a sample's eight corners and the 24 voxels of its cell
// gradient all lie in one page, as they lie in one brick of the raw codec: the packet path reads
// them with the same gathers, after one more gather in the page table. A page stores the
// volume's own scalar type (uint8 data: a byte a voxel; int16 as uint16 with a bias; float32 as
// floats): lossy codecs round to it, which loses nothing the input had.
//
// Pages are decoded the first time a ray samples them (from any thread) into a pool of at most
// `budget` bytes. When the pool is full, a CLOCK hand evicts pages no ray has touched since it
// last passed (second chance): rays set a page's bit when they enter it. Regions the rays skip
// (empty space) are never decoded, and a rank decodes only the pages its own rectangles' rays
// reach. The pool is allocated untouched, so only decoded pages become resident.
//
// Why a lane never reads a page while it is evicted and its slot refilled: the slots are
// reclaimed by quiescent states (QSBR, as in McKenney and Slingwine, "Read-copy update", 1998).
// A thread rendering a block is a Reader; it holds page offsets only within one sample step (the
// page-table gather, the corners, the gradient), and at the start of every step it declares that
// it holds none (quiesce: it records the cache's epoch). Eviction unmaps the page's table entry
// (so no new step finds it), then advances the epoch and retires the slot with the old epoch; a
// retired slot is refilled only once every Reader has recorded a later epoch or left its block.
// The hit path takes no lock and writes nothing shared: a page-table gather, and once per lane
// per page entered, a byte read (the CLOCK bit, written only when clear). Misses take a mutex to
// get a slot, then decode outside it. A lane that finds no slot it may take (a budget of a few
// pages, every slot retired in the current step) decodes its page into a scratch page of its
// own, used for that step only: the picture never depends on the budget.
//
// Under pressure (the renderer's --lod-under-pressure, for the views with coarser levels: svmm,
// ksvd), a lane whose page is not resident and finds no slot free without evicting samples level
// 1 for this step instead (from a second PageCache over that level, which the backend makes with
// a quarter of the budget: an eighth of the voxels per page of the volume for ksvd, a 64th for
// svmm's blocks of 4) and marks the page wanted; refill() decodes the wanted pages after the tile,
// evicting by CLOCK, at most a quarter of the pool per call, so that later frames find them. No
// page of the full-resolution pool is evicted while a frame renders in this mode.
//
// This is the decoded-brick cache of the GPU renderers behind the codecs (Gobbetti, Iglesias
// Guitian and Marton, "COVRA: a compression-domain output-sensitive volume rendering
// architecture", 2012; Guthe and Goesele, "Variable length coding for GPU-based direct volume
// rendering", 2016), kept per rank on the CPU.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <typeindex>
#include <typeinfo>
#include <vector>
#include <voxwall/codec/kernels/trilinear.hpp>
#include <voxwall/codec/volume.hpp>
#include <voxwall/core/parallel.hpp>
#include <voxwall/node/page_decode.hpp>

namespace voxwall::node {

// A level PageCache can hold pages of: a view (or one level of one) with a cache id unique per
// opened volume, its grid's size, and its voxels read one at a time through the ray's cache. A
// codec's view that meets it is paged with no edit outside the codec (node/src/cpu_blocks.hpp).
template <class L>
concept PageableLevel = requires(const L& l, typename L::RayCache& rc) {
  { l.cacheId } -> std::convertible_to<std::uint64_t>;
  { l.dimX + l.dimY + l.dimZ } -> std::convertible_to<int>;
  { l.maxX + l.maxY + l.maxZ } -> std::convertible_to<float>;
  { l.voxel(0, 0, 0, rc) } -> std::convertible_to<float>;
};

// What a page stores per voxel: the value as float(stored) + bias.
enum class PageFormat : std::uint8_t { UInt8, UInt16, Float32 };

class PageCache {
 public:
  static constexpr int kShift = pages::kShift;  // 32 voxels per page side
  static constexpr int kSide = pages::kSide;
  static constexpr int kLead = pages::kLead;  // a cell's page along an axis: (x + kLead) >> kShift
  static constexpr int kRow = pages::kRow;    // the apron: one voxel below, two above
  static constexpr int kSlice = kRow * kRow;
  static constexpr int kVoxels = pages::kVoxels;
  // A page's table entry: the element offset of its page in the pool, or one of these.
  // kWanted: absent, and waiting for refill() (lod under pressure).
  static constexpr std::int32_t kAbsent = -1, kFilling = -2, kWanted = -3;
  // Scratch pages per Reader: one per lane of the widest packet.
  static constexpr int kScratchPerReader = 16;

  // Counts since the cache was made (take differences for a frame).
  struct Counts {
    std::uint64_t hits = 0;       // lane samples that found their page resident
    std::uint64_t missed = 0;     // lane samples that did not (decoded, waited or scratch)
    std::uint64_t misses = 0;     // pages decoded into the pool
    std::uint64_t scratch = 0;    // pages decoded into a lane's scratch page (no slot free)
    std::uint64_t evictions = 0;  // pages evicted
    std::uint64_t coarse = 0;     // lane samples taken from a coarser level instead (of missed)
    std::uint64_t waited = 0;     // lane samples that waited for a page another thread decoded
  };

  // The storage of a volume of this scalar type.
  static PageFormat formatOf(codec::ScalarType type) {
    switch (type) {
      case codec::ScalarType::UInt8:
        return PageFormat::UInt8;
      case codec::ScalarType::UInt16:
      case codec::ScalarType::Int16:
        return PageFormat::UInt16;
      default:
        return PageFormat::Float32;
    }
  }
  static std::size_t valueBytes(PageFormat f) {
    return f == PageFormat::UInt8 ? 1 : f == PageFormat::UInt16 ? 2 : 4;
  }

  // Pages for `level` (a PageableLevel) of a volume of scalar type `type`, in at most
  // `budgetBytes` of decoded voxels, for up to `readers` threads at once. For levels of big bricks
  // (pages::sharesBricks: zfp's) up to an eighth of the budget holds decoded bricks that
  // neighbouring pages share (brick_memo.hpp).
  template <class Level>
  static std::unique_ptr<PageCache> make(const Level& level, codec::ScalarType type,
                                         std::uint64_t budgetBytes, int readers) {
    const std::uint64_t memo = memoBudget(level, budgetBytes, type);
    std::unique_ptr<PageCache> c(new PageCache(typeid(Level), level.cacheId, level.dimX, level.dimY,
                                               level.dimZ, type, budgetBytes - memo, readers));
    c->memo_ = makeMemo(level, type, budgetBytes);
    return c;
  }
  // The memo of bricks `make` gives `level`'s pages with this budget (null: none).
  template <class Level>
  static std::unique_ptr<pages::BrickMemo> makeMemo(const Level& level, codec::ScalarType type,
                                                    std::uint64_t budgetBytes) {
    const std::uint64_t memo = memoBudget(level, budgetBytes, type);
    if (!memo) return nullptr;
    return std::make_unique<pages::BrickMemo>(brickBytes<Level>(type), memo);
  }

  // What `make` would hold for `level` with this budget, in bytes: its pages and its memo of
  // bricks (what becomes resident when rays reach that many pages; scratch pages not counted).
  template <class Level>
  static std::uint64_t bytesFor(const Level& level, codec::ScalarType type,
                                std::uint64_t budgetBytes) {
    const PageFormat f = formatOf(type);
    const std::uint64_t memo = memoBudget(level, budgetBytes, type);
    return capacityFor(level.dimX, level.dimY, level.dimZ, f, budgetBytes - memo, 1) *
               std::uint64_t(kVoxels) * valueBytes(f) +
           (memo ? pages::BrickMemo::bytesFor(brickBytes<Level>(type), memo) : 0);
  }

  // Whether these are the pages of `level` (its view type, cacheId and size: each codec numbers
  // its volumes from 1) for this scalar type.
  template <class Level>
  bool holds(const Level& level, codec::ScalarType type, int readers) const {
    return std::type_index(typeid(Level)) == type_ && level.cacheId == id_ && level.dimX == dimX &&
           level.dimY == dimY && level.dimZ == dimZ && formatOf(type) == format_ &&
           readers <= readers_;
  }

  int dimX, dimY, dimZ;
  int pagesX, pagesY, pagesZ;

  PageFormat format() const { return format_; }
  // Added to a stored value to give the voxel (int16 data stored as uint16: -32768; else 0).
  float bias() const { return bias_; }
  // The page table, for gathers: the entry of page (px, py, pz) is at
  // (pz * pagesY + py) * pagesX + px.
  const std::int32_t* table() const { return reinterpret_cast<const std::int32_t*>(entry_.get()); }
  // The pool, for gathers (readable 8 bytes past its last element).
  const void* pool() const { return pool_.get(); }
  std::size_t pageBytes() const { return std::size_t(kVoxels) * valueBytes(format_); }
  std::size_t capacityPages() const { return std::size_t(capacity_); }
  // Pages mapped in the table now (each in a slot of its own; evicted ones not counted).
  std::size_t residentPages() const;
  // Slots ever written: the pool's resident part, since a written slot stays mapped.
  std::size_t touchedSlots() const;
  std::uint64_t allPagesBytes() const {
    return std::uint64_t(pagesX) * std::uint64_t(pagesY) * std::uint64_t(pagesZ) * pageBytes();
  }
  Counts counts() const;
  // The memo of decoded bricks shared by pages (null for levels without big bricks, or where the
  // budget leaves it no room).
  const pages::BrickMemo* memo() const { return memo_.get(); }
  // What is resident: the pages mapped now and the memo's bricks.
  std::uint64_t residentBytes() const {
    return std::uint64_t(residentPages()) * pageBytes() + (memo_ ? memo_->residentBytes() : 0);
  }

  // Marks page `page` used (CLOCK's second chance), where a lane enters it.
  void touch(std::int32_t page) {
    auto& bit = ref_[std::size_t(page)];
    if (!bit.load(std::memory_order_relaxed)) bit.store(1, std::memory_order_relaxed);
  }

  // A thread's registration while it samples pages (a block of the tile). Not copyable.
  class Reader {
   public:
    explicit Reader(PageCache& cache);
    ~Reader();
    Reader(const Reader&) = delete;
    Reader& operator=(const Reader&) = delete;

    PageCache& cache() const { return cache_; }
    // Whether a lane that misses samples a coarser level instead (PageCache::setPressure).
    bool pressure() const { return pressure_; }
    // Declares that this thread holds no page offset (the start of a sample step).
    void quiesce() {
      ++step_;
      const std::uint64_t e = cache_.epoch_.load(std::memory_order_seq_cst);
      if (e != seen_) {
        seen_ = e;
        cache_.reader_[std::size_t(index_)].seen.store(e, std::memory_order_seq_cst);
      }
    }
    // The pool offset of `page` for lane `lane` of this step: the page's slot after decoding it
    // from `level` where absent (or waiting for the thread decoding it), or a scratch page of
    // this lane's when no slot is free.
    template <class Level>
    std::int32_t fill(std::int32_t page, const Level& level, int lane);
    // Under pressure: the pool offset of `page` where it is resident, or after decoding it into
    // a slot that is free without evicting anything; else -1 (the lane samples a coarser level)
    // and the page is wanted by the next refill().
    template <class Level>
    std::int32_t fillIfRoom(std::int32_t page, const Level& level);

    std::uint64_t hits = 0, missed = 0, coarse = 0;  // added by the caller (Counts)

   private:
    PageCache& cache_;
    int index_ = -1;
    std::uint64_t seen_;
    Counts counts_;
    std::uint64_t step_ = 0;                        // steps begun (quiesce)
    std::int32_t scratchPage_[kScratchPerReader];   // the page each scratch slot holds
    std::uint64_t scratchStep_[kScratchPerReader];  // the step that last used it
    std::vector<std::int32_t> wanted_;              // pages this Reader marked kWanted
    bool pressure_;
    bool evicting_;
  };

  // Lod under pressure for the Readers made from now on (the backend sets it per tile).
  void setPressure(bool on) { pressure_ = on; }
  // Whether the Readers made from now on may evict a page to make room (the backend sets it per
  // tile). Off while decoding ahead of the rays (RankRenderer::decodeAhead): a page finds a free
  // slot or goes to a scratch page, so decoding ahead never evicts a page a frame holds.
  void setEvicting(bool on) { evicting_ = on; }

  // Decodes the pages lanes wanted under pressure since the last call (at most a quarter of the
  // pool, evicting by CLOCK; the rest are forgotten and wanted again when rays reach them), on
  // `threads` threads. Call it when no Reader is online (between tiles). Returns pages decoded.
  template <class Level>
  std::size_t refill(const Level& level, int threads);

 private:
  friend class Reader;
  static constexpr std::uint64_t kOffline = ~std::uint64_t(0);

  PageCache(const std::type_info& type, std::uint64_t id, int x, int y, int z,
            codec::ScalarType scalar, std::uint64_t budgetBytes, int readers);

  // Slots for the budget's worth of pages, at most every page of the volume, and together with
  // the readers' scratch pages no more than int32 offsets reach (narrow gathers address bytes).
  static std::uint64_t capacityFor(int x, int y, int z, PageFormat format,
                                   std::uint64_t budgetBytes, int readers);

  // A slot for a page (-1: none may be taken now), evicting where `evict`. Takes the mutex.
  std::int32_t takeSlot(bool evict = true);
  void evictLocked(std::size_t n);
  void reclaimLocked();
  // Publishes a filled slot's page (makes it evictable).
  void filled(std::int32_t slot, std::int32_t page);

  // The memo's part of the budget: an eighth, at most every brick of the level (with a quarter
  // more and 16 a shard for the shards' unevenness); 0 where that holds too few bricks to be of
  // use.
  template <class Level>
  static std::uint64_t memoBudget(const Level& level, std::uint64_t budgetBytes,
                                  codec::ScalarType type) {
    if constexpr (pages::sharesBricks<Level>()) {
      const std::uint64_t side = std::uint64_t(Level::kSide);
      const std::uint64_t bricks = (std::uint64_t(level.dimX) + side - 1) / side *
                                   ((std::uint64_t(level.dimY) + side - 1) / side) *
                                   ((std::uint64_t(level.dimZ) + side - 1) / side);
      const std::size_t brick = brickBytes<Level>(type);
      const std::uint64_t most = (bricks + bricks / 4 + 16 * pages::BrickMemo::kShards) * brick;
      const std::uint64_t memo = std::min(budgetBytes / 8, most);
      return pages::BrickMemo::bytesFor(brick, memo) ? memo : 0;
    } else {
      (void)level, (void)budgetBytes, (void)type;
      return 0;
    }
  }
  template <class Level>
  static std::size_t brickBytes(codec::ScalarType type) {
    if constexpr (pages::sharesBricks<Level>())
      return std::size_t(Level::kVoxels) * valueBytes(formatOf(type));
    else
      return 0;
  }

  // f(Stored{}) with the C++ type a page stores its voxels in (format_).
  template <class F>
  void withStored(F&& f) const;
  template <class Level>
  void decode(std::int32_t page, const Level& level, std::int32_t slot) const;
  // While another thread decodes `page` (kFilling): decodes the bricks of it that the memo lacks
  // (pages::helpDecodePage), where the level's pages share bricks; else nothing.
  template <class Level>
  void help(std::int32_t page, const Level& level) const;
  // Decodes `page` into `slot` (taken for it, its entry kFilling) and publishes it; returns its
  // pool offset.
  template <class Level>
  std::int32_t decodeInto(std::int32_t page, const Level& level, std::int32_t slot) {
    decode(page, level, slot);
    const std::int32_t offset = slot * kVoxels;
    entry_[std::size_t(page)].store(offset, std::memory_order_release);
    filled(slot, page);
    return offset;
  }

  std::type_index type_;
  std::uint64_t id_;
  PageFormat format_;
  float bias_ = 0.0f;
  int readers_;
  std::int32_t capacity_ = 0;
  std::unique_ptr<std::atomic<std::int32_t>[]> entry_;  // per page: its offset or kAbsent...
  std::unique_ptr<std::atomic<std::uint8_t>[]> ref_;    // per page: CLOCK's bit
  std::unique_ptr<std::byte[]> pool_;
  std::unique_ptr<pages::BrickMemo> memo_;
  std::atomic<std::uint64_t> epoch_{1};
  struct alignas(64) ReaderSlot {
    std::atomic<std::uint64_t> seen{kOffline};
    std::atomic<bool> busy{false};
  };
  std::unique_ptr<ReaderSlot[]> reader_;

  // Under mutex_:
  mutable std::mutex mutex_;
  std::vector<std::int32_t> slotPage_;  // per slot: its page, or -1 (free, filling, retired)
  std::vector<std::int32_t> free_;      // slots to refill
  struct Retired {
    std::int32_t slot;
    std::uint64_t epoch;
  };
  std::deque<Retired> retired_;
  std::int32_t fresh_ = 0;  // slots never written are fresh_ .. capacity_ - 1
  std::int32_t hand_ = 0;   // CLOCK's
  std::size_t reserve_ = 0;
  std::atomic<std::size_t> resident_{0};
  Counts totals_;                     // of Readers that left
  std::vector<std::int32_t> wanted_;  // pages in state kWanted, for refill()
  bool pressure_ = false;
  bool evicting_ = true;
};

template <class F>
void PageCache::withStored(F&& f) const {
  switch (format_) {
    case PageFormat::UInt8:
      return f(std::uint8_t{});
    case PageFormat::UInt16:
      return f(std::uint16_t{});
    case PageFormat::Float32:
      return f(float{});
  }
}

template <class Level>
void PageCache::decode(std::int32_t page, const Level& level, std::int32_t slot) const {
  const int px = page % pagesX, py = (page / pagesX) % pagesY, pz = page / pagesX / pagesY;
  std::byte* at = pool_.get() + std::size_t(slot) * pageBytes();
  withStored([&]<class Stored>(Stored) {
    pages::decodePage(level, px, py, pz, bias_, reinterpret_cast<Stored*>(at), memo_.get());
  });
}

template <class Level>
void PageCache::help(std::int32_t page, const Level& level) const {
  if constexpr (pages::sharesBricks<Level>()) {
    if (!memo_ || !memo_->usable()) return;
    const int px = page % pagesX, py = (page / pagesX) % pagesY, pz = page / pagesX / pagesY;
    const auto& entry = entry_[std::size_t(page)];
    const auto done = [&] { return entry.load(std::memory_order_acquire) != kFilling; };
    withStored([&]<class Stored>(Stored) {
      pages::helpDecodePage<Level, Stored>(level, px, py, pz, bias_, *memo_, done);
    });
  } else {
    (void)page, (void)level;
  }
}

template <class Level>
std::int32_t PageCache::Reader::fill(std::int32_t page, const Level& level, int lane) {
  PageCache& c = cache_;
  auto& entry = c.entry_[std::size_t(page)];
  bool waiting = false;
  for (;;) {
    std::int32_t state = entry.load(std::memory_order_acquire);
    if (state >= 0) return state;
    if (state == kFilling) {  // another thread decodes it: it never waits on anything
      if (!waiting) {
        ++counts_.waited, waiting = true;
        c.help(page, level);  // its bricks from the other end, where they are big
        continue;
      }
      std::this_thread::yield();
      continue;
    }
    if (!entry.compare_exchange_weak(state, kFilling, std::memory_order_acq_rel)) continue;
    const std::int32_t slot = c.takeSlot(evicting_);
    if (slot < 0) {
      entry.store(kAbsent, std::memory_order_release);
      // A scratch page of this Reader's: one already holding the page, else one no lane of
      // this step uses (there is one per lane).
      int k = 0;
      while (k < kScratchPerReader && scratchPage_[k] != page) ++k;
      const bool have = k < kScratchPerReader;
      if (!have) {
        k = lane;
        if (scratchStep_[k] == step_)
          for (k = 0; scratchStep_[k] == step_; ++k) {
          }
      }
      const std::int32_t at = c.capacity_ + index_ * kScratchPerReader + k;
      if (!have) {
        c.decode(page, level, at);
        scratchPage_[k] = page;
        ++counts_.scratch;
      }
      scratchStep_[k] = step_;
      return at * kVoxels;
    }
    ++counts_.misses;
    return c.decodeInto(page, level, slot);
  }
}

template <class Level>
std::int32_t PageCache::Reader::fillIfRoom(std::int32_t page, const Level& level) {
  PageCache& c = cache_;
  auto& entry = c.entry_[std::size_t(page)];
  bool waiting = false;
  for (;;) {
    std::int32_t state = entry.load(std::memory_order_acquire);
    if (state >= 0) return state;
    if (state == kFilling) {  // another thread decodes it into a slot it had free: wait
      if (!waiting) {
        ++counts_.waited, waiting = true;
        c.help(page, level);
        continue;
      }
      std::this_thread::yield();
      continue;
    }
    if (state == kWanted) return -1;
    if (!entry.compare_exchange_weak(state, kFilling, std::memory_order_acq_rel)) continue;
    const std::int32_t slot = c.takeSlot(false);
    if (slot < 0) {
      entry.store(kWanted, std::memory_order_release);
      wanted_.push_back(page);
      return -1;
    }
    ++counts_.misses;
    return c.decodeInto(page, level, slot);
  }
}

template <class Level>
std::size_t PageCache::refill(const Level& level, int threads) {
  std::vector<std::int32_t> pages;
  {
    std::lock_guard lock(mutex_);
    pages.swap(wanted_);
  }
  // Slots first (no Reader is online, so every slot evicted now is free at once), then the
  // decoding on every thread.
  const std::size_t most = std::max<std::size_t>(1, std::size_t(capacity_) / 4);
  std::vector<std::pair<std::int32_t, std::int32_t>> jobs;  // page, slot
  for (const std::int32_t page : pages) {
    auto& entry = entry_[std::size_t(page)];
    std::int32_t state = kWanted;
    if (!entry.compare_exchange_strong(state, kFilling, std::memory_order_acq_rel)) continue;
    const std::int32_t slot = jobs.size() < most ? takeSlot(true) : -1;
    if (slot < 0) {
      entry.store(kAbsent, std::memory_order_release);  // wanted again when a ray reaches it
      continue;
    }
    jobs.emplace_back(page, slot);
  }
  voxwall::parallelFor(jobs.size(), threads,
                       [&](std::size_t i) { decodeInto(jobs[i].first, level, jobs[i].second); });
  std::lock_guard lock(mutex_);
  totals_.misses += jobs.size();
  return jobs.size();
}

}  // namespace voxwall::node
