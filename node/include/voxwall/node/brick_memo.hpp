// Decoded bricks that the pages of one level share, for bricks of 16^3 (zfp's; see
// pages::sharesBricks for why not smaller ones).
//
// A page stores 35 voxels a side: its cells' 32 and an apron of one voxel below and two above,
// starting on a multiple of 16 (page_decode.hpp). With bricks of 16^3 that is 3 bricks a side,
// 27 decoded for 8 bricks' worth of voxels, and the bricks on its faces lie under the pages
// beside it too, which need them again. The memo keeps what the page decoder decoded, in
// the page's own storage type (the values the page stores: a byte a voxel for uint8 data), so that
// a brick is decoded about once whichever thread and page meet it first.
//
// It is shared by the threads that decode pages (the rays' and the pass ahead of them): 64
// shards, each a mutex, a map from the brick's key to its slot and a ring of slots replaced
// oldest first. A thread copies a brick out under its shard's lock (a few KiB), so a slot is never
// read while it is refilled. The slots are allocated untouched: only bricks kept become resident.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

namespace voxwall::node::pages {

class BrickMemo {
 public:
  // Slots of `brickBytes` each for about `budgetBytes` (at least one per shard, or none at all
  // when the budget holds fewer than that: usable() is false).
  BrickMemo(std::size_t brickBytes, std::uint64_t budgetBytes);

  static constexpr int kShards = 64;

  bool usable() const { return perShard_ > 0; }
  std::size_t brickBytes() const { return brickBytes_; }
  // The bytes of its slots: what it holds once full.
  std::uint64_t capacityBytes() const {
    return std::uint64_t(perShard_) * kShards * std::uint64_t(brickBytes_);
  }
  // The bytes of the slots written so far: what is resident.
  std::uint64_t residentBytes() const {
    return used_.load(std::memory_order_relaxed) * std::uint64_t(brickBytes_);
  }
  // The most bytes a memo made with this budget holds (0 where it would not be usable).
  static std::uint64_t bytesFor(std::size_t brickBytes, std::uint64_t budgetBytes);

  // Copies brick `key`'s bytes into `out` and returns true where it is held.
  bool find(std::uint64_t key, void* out);
  // Whether brick `key` is held now (find() may still miss it: another thread may replace it).
  bool holds(std::uint64_t key);
  // Keeps `brick` (brickBytes) as brick `key`'s, replacing its shard's oldest where full.
  void keep(std::uint64_t key, const void* brick);

  struct Counts {
    std::uint64_t found = 0, kept = 0, replaced = 0;
  };
  Counts counts() const;

 private:
  struct Shard {
    std::mutex mutex;
    std::unordered_map<std::uint64_t, std::uint32_t> slotOf;
    std::vector<std::uint64_t> keyOf;  // per slot in use, its brick's key
    std::uint32_t next = 0;            // the slot written next (the oldest once full)
    Counts counts;
  };
  std::byte* slot(int shard, std::uint32_t s) const {
    return slots_.get() + (std::size_t(shard) * perShard_ + s) * brickBytes_;
  }

  std::size_t brickBytes_;
  std::uint32_t perShard_;
  std::unique_ptr<std::byte[]> slots_;
  std::unique_ptr<Shard[]> shards_;
  std::atomic<std::uint64_t> used_{0};  // slots written
};

}  // namespace voxwall::node::pages
