#include <algorithm>
#include <cstring>
#include <voxwall/node/brick_memo.hpp>

namespace voxwall::node::pages {

namespace {

std::uint32_t slotsPerShard(std::size_t brickBytes, std::uint64_t budgetBytes) {
  if (brickBytes == 0) return 0;
  const std::uint64_t slots = budgetBytes / brickBytes / BrickMemo::kShards;
  return std::uint32_t(std::min<std::uint64_t>(slots, std::uint64_t(1) << 24));
}

// Keys of neighbouring bricks differ in their low bits: mixed so that they spread over shards.
int shardOf(std::uint64_t key) {
  key ^= key >> 31;
  key *= 0x9E3779B97F4A7C15ull;
  return int(key >> 58);  // 64 shards
}

}  // namespace

BrickMemo::BrickMemo(std::size_t brickBytes, std::uint64_t budgetBytes)
    : brickBytes_(brickBytes), perShard_(slotsPerShard(brickBytes, budgetBytes)) {
  static_assert(kShards == 64, "shardOf takes the top 6 bits");
  if (!perShard_) return;
  // Default-initialised: the kernel maps a slot's memory when it is first written.
  slots_.reset(new std::byte[std::size_t(perShard_) * kShards * brickBytes_]);
  shards_ = std::make_unique<Shard[]>(kShards);
}

std::uint64_t BrickMemo::bytesFor(std::size_t brickBytes, std::uint64_t budgetBytes) {
  return std::uint64_t(slotsPerShard(brickBytes, budgetBytes)) * kShards * brickBytes;
}

bool BrickMemo::find(std::uint64_t key, void* out) {
  if (!perShard_) return false;
  const int h = shardOf(key);
  Shard& s = shards_[std::size_t(h)];
  std::lock_guard lock(s.mutex);
  const auto it = s.slotOf.find(key);
  if (it == s.slotOf.end()) return false;
  std::memcpy(out, slot(h, it->second), brickBytes_);
  ++s.counts.found;
  return true;
}

bool BrickMemo::holds(std::uint64_t key) {
  if (!perShard_) return false;
  Shard& s = shards_[std::size_t(shardOf(key))];
  std::lock_guard lock(s.mutex);
  return s.slotOf.contains(key);
}

void BrickMemo::keep(std::uint64_t key, const void* brick) {
  if (!perShard_) return;
  const int h = shardOf(key);
  Shard& s = shards_[std::size_t(h)];
  std::lock_guard lock(s.mutex);
  if (s.slotOf.contains(key)) return;  // another thread decoded it too
  const std::uint32_t at = s.next;
  if (at < s.keyOf.size()) {
    s.slotOf.erase(s.keyOf[at]);
    s.keyOf[at] = key;
    ++s.counts.replaced;
  } else {
    s.keyOf.push_back(key);
    used_.fetch_add(1, std::memory_order_relaxed);
  }
  s.next = at + 1 == perShard_ ? 0 : at + 1;
  s.slotOf.emplace(key, at);
  std::memcpy(slot(h, at), brick, brickBytes_);
  ++s.counts.kept;
}

BrickMemo::Counts BrickMemo::counts() const {
  Counts c;
  if (!perShard_) return c;
  for (int h = 0; h < kShards; ++h) {
    Shard& s = shards_[std::size_t(h)];
    std::lock_guard lock(s.mutex);
    c.found += s.counts.found, c.kept += s.counts.kept, c.replaced += s.counts.replaced;
  }
  return c;
}

}  // namespace voxwall::node::pages
