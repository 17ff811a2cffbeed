#include <voxwall/node/page_cache.hpp>

namespace voxwall::node {

PageCache::PageCache(const std::type_info& type, std::uint64_t id, int x, int y, int z,
                     codec::ScalarType scalar, std::uint64_t budgetBytes, int readers)
    : dimX(x),
      dimY(y),
      dimZ(z),
      type_(type),
      id_(id),
      format_(formatOf(scalar)),
      // int16 data is stored as uint16 values 0 .. 65535 for -32768 .. 32767.
      bias_(scalar == codec::ScalarType::Int16 ? -32768.0f : 0.0f),
      readers_(std::max(1, readers)) {
  if (x <= 0 || y <= 0 || z <= 0) throw std::invalid_argument("decoded pages of an empty volume");
  pagesX = pages::pagesAlong(x), pagesY = pages::pagesAlong(y), pagesZ = pages::pagesAlong(z);
  const std::uint64_t pages = std::uint64_t(pagesX) * std::uint64_t(pagesY) * std::uint64_t(pagesZ);
  if (pages >= (std::uint64_t(1) << 31)) throw std::invalid_argument("too many decoded pages");
  capacity_ = std::int32_t(capacityFor(x, y, z, format_, budgetBytes, readers_));
  entry_ = std::make_unique<std::atomic<std::int32_t>[]>(std::size_t(pages));
  ref_ = std::make_unique<std::atomic<std::uint8_t>[]>(std::size_t(pages));
  for (std::uint64_t i = 0; i < pages; ++i) {
    entry_[i].store(kAbsent, std::memory_order_relaxed);
    ref_[i].store(0, std::memory_order_relaxed);
  }
  reader_ = std::make_unique<ReaderSlot[]>(std::size_t(readers_));
  slotPage_.assign(std::size_t(capacity_), -1);
  // Evicted ahead of need, so that a miss mostly finds a slot every Reader has left behind.
  reserve_ = std::size_t(capacity_) / 64;
  // Default-initialised: the kernel maps the pool's memory as pages are written.
  const std::size_t slots = std::size_t(capacity_) + std::size_t(readers_) * kScratchPerReader;
  pool_.reset(new std::byte[slots * pageBytes() + 8]);
}

std::uint64_t PageCache::capacityFor(int x, int y, int z, PageFormat format,
                                     std::uint64_t budgetBytes, int readers) {
  const std::uint64_t pages = std::uint64_t(pages::pagesAlong(x)) *
                              std::uint64_t(pages::pagesAlong(y)) *
                              std::uint64_t(pages::pagesAlong(z));
  // Float pages are gathered by element index, narrow ones by byte offset.
  const std::uint64_t unit = format == PageFormat::Float32 ? 1 : valueBytes(format);
  const std::uint64_t slots = ((std::uint64_t(1) << 31) - 64) / (std::uint64_t(kVoxels) * unit);
  const std::uint64_t scratch = std::uint64_t(std::max(1, readers)) * kScratchPerReader;
  const std::uint64_t maxPages = slots > scratch ? slots - scratch : 0;
  std::uint64_t capacity = budgetBytes / (std::uint64_t(kVoxels) * valueBytes(format));
  capacity = std::min(capacity, maxPages);
  return std::min(capacity, pages);
}

std::size_t PageCache::residentPages() const { return resident_.load(std::memory_order_relaxed); }

std::size_t PageCache::touchedSlots() const {
  std::lock_guard lock(mutex_);
  return std::size_t(fresh_);
}

PageCache::Counts PageCache::counts() const {
  std::lock_guard lock(mutex_);
  return totals_;
}

std::int32_t PageCache::takeSlot(bool evict) {
  std::lock_guard lock(mutex_);
  std::int32_t slot = -1;
  if (free_.empty()) reclaimLocked();
  if (!free_.empty()) {
    slot = free_.back();
    free_.pop_back();
  } else if (fresh_ < capacity_) {
    slot = fresh_++;
  } else if (!evict) {
    return -1;
  } else {
    evictLocked(1 + reserve_);
    reclaimLocked();
    if (free_.empty()) return -1;
    slot = free_.back();
    free_.pop_back();
  }
  // Keep a reserve on its way back to the free list.
  if (evict && fresh_ >= capacity_ && free_.size() + retired_.size() < reserve_)
    evictLocked(reserve_ - free_.size() - retired_.size());
  return slot;
}

void PageCache::filled(std::int32_t slot, std::int32_t page) {
  ref_[std::size_t(page)].store(1, std::memory_order_relaxed);
  std::lock_guard lock(mutex_);
  slotPage_[std::size_t(slot)] = page;
  resident_.fetch_add(1, std::memory_order_relaxed);
}

void PageCache::evictLocked(std::size_t n) {
  // CLOCK: at most two laps (the first may only clear bits).
  for (std::size_t step = 0, laps = 2 * std::size_t(capacity_); n > 0 && step < laps; ++step) {
    const std::int32_t slot = hand_;
    hand_ = hand_ + 1 < capacity_ ? hand_ + 1 : 0;
    const std::int32_t page = slotPage_[std::size_t(slot)];
    if (page < 0) continue;  // free, being filled or retired
    auto& bit = ref_[std::size_t(page)];
    if (bit.load(std::memory_order_relaxed)) {
      bit.store(0, std::memory_order_relaxed);
      continue;
    }
    // Unmap first: a step that starts after the epoch moves cannot find the page.
    entry_[std::size_t(page)].store(kAbsent, std::memory_order_seq_cst);
    slotPage_[std::size_t(slot)] = -1;
    const std::uint64_t epoch = epoch_.fetch_add(1, std::memory_order_seq_cst);
    retired_.push_back({slot, epoch});
    resident_.fetch_sub(1, std::memory_order_relaxed);
    ++totals_.evictions;
    --n;
  }
}

void PageCache::reclaimLocked() {
  if (retired_.empty()) return;
  std::uint64_t oldest = kOffline;
  for (int r = 0; r < readers_; ++r)
    oldest = std::min(oldest, reader_[std::size_t(r)].seen.load(std::memory_order_seq_cst));
  // A Reader that recorded an epoch after the slot's retirement started its step after the unmap.
  while (!retired_.empty() && retired_.front().epoch < oldest) {
    free_.push_back(retired_.front().slot);
    retired_.pop_front();
  }
}

PageCache::Reader::Reader(PageCache& cache)
    : cache_(cache), pressure_(cache.pressure_), evicting_(cache.evicting_) {
  for (auto& p : scratchPage_) p = -1;
  for (auto& p : scratchStep_) p = ~std::uint64_t(0);
  // A slot of its own: the backend makes the cache for as many readers as it has threads, so
  // one is free unless another thread is just leaving its block.
  for (;;) {
    for (int r = 0; r < cache.readers_ && index_ < 0; ++r) {
      bool expected = false;
      if (cache.reader_[std::size_t(r)].busy.compare_exchange_strong(expected, true,
                                                                     std::memory_order_acquire))
        index_ = r;
    }
    if (index_ >= 0) break;
    std::this_thread::yield();
  }
  seen_ = cache.epoch_.load(std::memory_order_seq_cst);
  cache.reader_[std::size_t(index_)].seen.store(seen_, std::memory_order_seq_cst);
}

PageCache::Reader::~Reader() {
  auto& slot = cache_.reader_[std::size_t(index_)];
  slot.seen.store(kOffline, std::memory_order_seq_cst);
  {
    std::lock_guard lock(cache_.mutex_);
    cache_.totals_.hits += hits;
    cache_.totals_.missed += missed;
    cache_.totals_.misses += counts_.misses;
    cache_.totals_.scratch += counts_.scratch;
    cache_.totals_.coarse += coarse;
    cache_.totals_.waited += counts_.waited;
    cache_.wanted_.insert(cache_.wanted_.end(), wanted_.begin(), wanted_.end());
  }
  slot.busy.store(false, std::memory_order_release);
}

}  // namespace voxwall::node
