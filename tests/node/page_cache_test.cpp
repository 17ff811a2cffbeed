// The decoded-page cache on its own: threads that evict each other's pages from a pool of a few
// slots never read a voxel of another page than the one they asked for (the quiescent-state
// reclamation of page_cache.hpp), the budget, formats and counts hold, and pages of big bricks
// share their bricks through the memo (brick_memo.hpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <random>
#include <thread>
#include <vector>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/node/page_cache.hpp>
#include <voxwall/node/render_volume.hpp>

using namespace voxwall;
using namespace voxwall::node;

namespace {

// A level whose voxels are a formula of their position.
struct Formula {
  struct RayCache {};
  std::uint64_t cacheId = 1;
  int dimX = 100, dimY = 70, dimZ = 40;
  static float value(int x, int y, int z) { return float((x * 7 + y * 13 + z * 29) % 251); }
  float voxel(int x, int y, int z, RayCache&) const { return value(x, y, z); }
};

}  // namespace

// Where pages are cut: every cell of an axis has a page, which stores the cell's corners and the
// voxels its gradient reads (one below, two above); every page holds a cell; a page's voxels
// start on a multiple of 16, so that they lie over 3 bricks of 16 a side.
TEST(PageCache, PagesAreCutSoThatTheirVoxelsStartOnAMultipleOf16) {
  for (int dim = 1; dim <= 200; ++dim) {
    const int n = pages::pagesAlong(dim);
    std::vector<int> cells(std::size_t(n), 0);
    for (int i = 0; i < dim; ++i) {
      const int p = pages::pageOf(i);
      ASSERT_GE(p, 0);
      ASSERT_LT(p, n) << "dim " << dim << " cell " << i;
      ++cells[std::size_t(p)];
      EXPECT_GE(i - 1, pages::firstVoxel(p));
      EXPECT_LE(i + 2, pages::firstVoxel(p) + pages::kRow - 1);
    }
    for (int p = 0; p < n; ++p) {
      EXPECT_GT(cells[std::size_t(p)], 0) << "dim " << dim << " page " << p;
      EXPECT_LE(cells[std::size_t(p)], pages::kSide);
      EXPECT_EQ((pages::firstVoxel(p) + 32) % 16, 0);
      const int first = pages::firstVoxel(p), last = first + pages::kRow - 1;
      EXPECT_EQ(last / 16 - first / 16 + 1, 3) << "bricks of 16 under page " << p;
    }
  }
}

TEST(PageCache, ThreadsEvictingEachOtherNeverReadAnotherPagesVoxels) {
  const Formula level;
  const std::uint64_t page = std::uint64_t(PageCache::kVoxels);  // bytes of a uint8 page
  const auto cache = PageCache::make(level, codec::ScalarType::UInt8, 3 * page, 4);
  ASSERT_EQ(cache->capacityPages(), 3u);
  ASSERT_EQ(cache->pageBytes(), page);
  const int pages = cache->pagesX * cache->pagesY * cache->pagesZ;
  ASSERT_EQ(pages, 4 * 3 * 2);
  const auto* pool = static_cast<const std::uint8_t*>(cache->pool());
  std::atomic<int> wrong{0};
  auto worker = [&](unsigned seed) {
    std::mt19937 rng(seed);
    for (int block = 0; block < 60; ++block) {
      PageCache::Reader reader(*cache);
      for (int step = 0; step < 40; ++step) {
        reader.quiesce();
        std::int32_t asked[8], at[8];
        for (int lane = 0; lane < 8; ++lane) {
          asked[lane] = std::int32_t(rng() % unsigned(pages));
          at[lane] = reader.fill(asked[lane], level, lane);
        }
        // Read them all after every lane's fill: other threads evict and refill meanwhile.
        for (int lane = 0; lane < 8; ++lane) {
          const int px = asked[lane] % cache->pagesX,
                    py = asked[lane] / cache->pagesX % cache->pagesY;
          const int pz = asked[lane] / cache->pagesX / cache->pagesY;
          for (int probe = 0; probe < 16; ++probe) {
            const int x = int(rng() % 32), y = int(rng() % 32), z = int(rng() % 32);
            // Stored voxel x + 1 along an axis is the page's first voxel plus x + 1.
            const int gx = pages::firstVoxel(px) + x + 1, gy = pages::firstVoxel(py) + y + 1,
                      gz = pages::firstVoxel(pz) + z + 1;
            if (gx < 0 || gy < 0 || gz < 0) continue;
            if (gx >= level.dimX || gy >= level.dimY || gz >= level.dimZ) continue;
            const std::uint8_t v =
                pool[std::size_t(at[lane]) + std::size_t(x + 1) +
                     std::size_t(y + 1) * PageCache::kRow + std::size_t(z + 1) * PageCache::kSlice];
            if (float(v) != Formula::value(gx, gy, gz)) wrong.fetch_add(1);
          }
        }
      }
    }
  };
  std::vector<std::thread> threads;
  for (unsigned t = 0; t < 4; ++t) threads.emplace_back(worker, 17 + t);
  for (auto& t : threads) t.join();
  EXPECT_EQ(wrong.load(), 0);
  const PageCache::Counts c = cache->counts();
  EXPECT_GT(c.evictions, 0u);
  EXPECT_GT(c.misses, 3u);
  EXPECT_LE(cache->residentPages(), 3u);
  EXPECT_LE(cache->touchedSlots(), 3u);
}

// Every page once with room for all: nothing evicted, and each scalar type in its own width.
TEST(PageCache, RoomForEveryPageDecodesEachOnce) {
  const Formula level;
  for (auto type : {codec::ScalarType::UInt8, codec::ScalarType::UInt16, codec::ScalarType::Int16,
                    codec::ScalarType::Float32}) {
    const auto cache = PageCache::make(level, type, std::uint64_t(1) << 30, 1);
    EXPECT_EQ(cache->pageBytes(), std::size_t(PageCache::kVoxels) * codec::scalarBytes(type));
    EXPECT_EQ(cache->capacityPages(), 24u);
    PageCache::Reader reader(*cache);
    for (int round = 0; round < 2; ++round)
      for (std::int32_t p = 0; p < 24; ++p) {
        reader.quiesce();
        EXPECT_GE(reader.fill(p, level, 0), 0);
      }
  }
  const auto cache = PageCache::make(level, codec::ScalarType::UInt8, std::uint64_t(1) << 30, 1);
  {
    PageCache::Reader reader(*cache);
    for (std::int32_t p = 0; p < 24; ++p) (void)reader.fill(p, level, 0);
    for (std::int32_t p = 0; p < 24; ++p) (void)reader.fill(p, level, 0);
  }
  EXPECT_EQ(cache->counts().misses, 24u);
  EXPECT_EQ(cache->counts().evictions, 0u);
  EXPECT_EQ(cache->residentPages(), 24u);
  // The size a budget allows, in whole pages; under one page, none.
  EXPECT_EQ(PageCache::bytesFor(level, codec::ScalarType::Float32, 5 * 4 * PageCache::kVoxels),
            5u * 4u * PageCache::kVoxels);
  EXPECT_EQ(PageCache::bytesFor(level, codec::ScalarType::UInt8, PageCache::kVoxels - 1), 0u);
}

namespace {

// A `dims` box of a Shepp-Logan phantom of `side`^3 voxels, from voxel `at` on.
codec::Volume sheppLoganCrop(int side, glm::ivec3 dims, glm::ivec3 at) {
  const codec::Volume sl = codec::generateSheppLogan(side);
  codec::Volume crop = codec::Volume::allocate(dims, codec::ScalarType::UInt8);
  const auto index = [](int x, int y, int z, glm::ivec3 d) {
    return (std::size_t(z) * std::size_t(d.y) + std::size_t(y)) * std::size_t(d.x) + std::size_t(x);
  };
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x)
        crop.as<std::uint8_t>()[index(x, y, z, dims)] =
            sl.as<std::uint8_t>()[index(x + at.x, y + at.y, z + at.z, glm::ivec3(side))];
  crop.computeRange();
  return crop;
}

// Every page of `volume`'s paged level, decoded a brick at a time and voxel by voxel, in every
// page format: the number of pages compared (0: no paged level), and any voxel that differs fails.
int expectPagesDecodeAlike(const RenderVolume& volume, const std::string& name) {
  int compared = 0;
  std::visit(
      [&](const auto& view) {
        using Level = std::remove_cvref_t<decltype(pages::pagedLevel(view))>;
        if constexpr (PageableLevel<Level>) {
          const Level& level = pages::pagedLevel(view);
          const auto each = [&](auto zero, float bias) {
            using Stored = decltype(zero);
            std::vector<Stored> fast(pages::kVoxels), slow(pages::kVoxels);
            for (int pz = 0; pz < pages::pagesAlong(level.dimZ); ++pz)
              for (int py = 0; py < pages::pagesAlong(level.dimY); ++py)
                for (int px = 0; px < pages::pagesAlong(level.dimX); ++px) {
                  pages::decodePage(level, px, py, pz, bias, fast.data());
                  pages::decodePageByVoxel(level, px, py, pz, bias, slow.data());
                  ASSERT_EQ(fast, slow) << name << " page " << px << "," << py << "," << pz;
                  ++compared;
                }
          };
          each(std::uint8_t{}, 0.0f);
          each(std::uint16_t{}, -32768.0f);
          each(float{}, 0.0f);
        }
      },
      volume.view());
  return compared;
}

}  // namespace

// A page decoded a brick at a time (the brick codecs' fast path) holds the very values the
// reference decode through the view's voxel() gives, for every codec's samples and for a volume of
// several pages (clamped faces, bricks across page borders, runs of equal bricks).
TEST(PageDecode, EveryCodecsPagesByBrickEqualThePagesByVoxel) {
  voxwall::Progress quiet;
  // 70 x 40 x 35: three pages wide, two high, two deep; bricks of 4, 6, 8, 16 cross page borders.
  const codec::Volume odd = sheppLoganCrop(70, {70, 40, 35}, {0, 15, 17});
  int bricked = 0;
  std::string report;
  for (const codec::Codec* c : codec::codecs()) {
    for (codec::CodecSample& sample : c->samples()) {
      try {
        expectPagesDecodeAlike(RenderVolume::fromCompressed(std::move(sample.volume)), sample.name);
      } catch (const FormatError&) {
        // a sample the renderer does not take (RGBA svmm)
      }
    }
    const auto volume = RenderVolume::fromCompressed(c->encode(odd, {}, quiet, report));
    const int pages = expectPagesDecodeAlike(volume, std::string(c->name()));
    EXPECT_TRUE(pages == 0 || pages == 3 * 12) << c->name() << ": " << pages;
    bricked += pages > 0;
  }
  EXPECT_GE(bricked, 5);  // vq, ksvd, tvq, zfp, svmm
}

// The memo of decoded bricks (brick_memo.hpp) on its own: what it keeps it gives back, a full
// shard replaces its oldest brick, and a budget under a brick a shard makes none.
TEST(BrickMemo, KeepsFindsAndReplacesTheOldest) {
  pages::BrickMemo tiny(64, 64 * pages::BrickMemo::kShards - 1);
  EXPECT_FALSE(tiny.usable());
  EXPECT_EQ(pages::BrickMemo::bytesFor(64, 64 * pages::BrickMemo::kShards - 1), 0u);
  std::vector<std::uint8_t> brick(64), out(64);
  tiny.keep(1, brick.data());
  EXPECT_FALSE(tiny.find(1, out.data()));

  pages::BrickMemo memo(64, 2 * 64 * pages::BrickMemo::kShards);  // two bricks a shard
  EXPECT_TRUE(memo.usable());
  EXPECT_EQ(memo.capacityBytes(), 2u * 64u * pages::BrickMemo::kShards);
  for (std::uint64_t key = 0; key < 1000; ++key) {
    std::fill(brick.begin(), brick.end(), std::uint8_t(key * 7));
    memo.keep(key, brick.data());
    ASSERT_TRUE(memo.find(key, out.data()));
    ASSERT_EQ(out, brick);
  }
  // Each shard holds its last two bricks: 128 of the 1000, and the newest are among them.
  int held = 0;
  for (std::uint64_t key = 0; key < 1000; ++key)
    if (memo.find(key, out.data())) {
      ++held;
      EXPECT_EQ(out[0], std::uint8_t(key * 7));
    }
  EXPECT_EQ(held, 2 * pages::BrickMemo::kShards);
  EXPECT_TRUE(memo.find(999, out.data()));
  EXPECT_EQ(memo.counts().kept, 1000u);
  EXPECT_EQ(memo.counts().replaced, 1000u - 128u);
  EXPECT_EQ(memo.residentBytes(), 128u * 64u);
}

namespace {

// zfp's file of an 80 x 70 x 66 Shepp-Logan crop (3 x 3 x 3 pages, bricks across every page
// border).
RenderVolume zfpCrop() {
  voxwall::Progress quiet;
  const codec::Volume crop = sheppLoganCrop(80, {80, 70, 66}, {0, 5, 7});
  std::string report;
  return RenderVolume::fromCompressed(codec::codecNamed("zfp").encode(crop, {}, quiet, report));
}

// f(level) with the paged level of zfpCrop()'s view (5^3 bricks of 16^3, 3^3 pages), whose pages
// share bricks.
template <class F>
void withZfpPagedLevel(F&& f) {
  const RenderVolume volume = zfpCrop();
  std::visit(
      [&](const auto& view) {
        using Level = std::remove_cvref_t<decltype(pages::pagedLevel(view))>;
        if constexpr (pages::sharesBricks<Level>())
          f(pages::pagedLevel(view));
        else
          ADD_FAILURE() << "zfp's paged level has no big bricks";
      },
      volume.view());
}

}  // namespace

// A thread that finds a page being decoded decodes its bricks into the memo from the other end
// (PageCache::Reader::fill): it stops as soon as the page is there, and the page then decoded
// through the memo takes every brick from it and equals the reference.
TEST(PageDecode, AThreadWaitingForAPageOfBigBricksDecodesItsBricksFromTheOtherEnd) {
  withZfpPagedLevel([&](const auto& level) {
    using Level = std::remove_cvref_t<decltype(level)>;
    const auto memoOfRoom = [] {
      return pages::BrickMemo(Level::kVoxels,
                              125 * pages::BrickMemo::kShards * std::uint64_t(Level::kVoxels));
    };
    // The page in the middle of 3^3: its 35 voxels a side (16 .. 50) lie over 3^3 bricks of 16^3
    // (pages cut at multiples of 32 would lie over 4^3).
    pages::BrickMemo stopped = memoOfRoom();
    int asked = 0;
    pages::helpDecodePage<Level, std::uint8_t>(level, 1, 1, 1, 0.0f, stopped,
                                               [&] { return ++asked > 5; });
    EXPECT_EQ(stopped.counts().kept, 5u);  // the page was there after five bricks
    pages::BrickMemo memo = memoOfRoom();
    pages::helpDecodePage<Level, std::uint8_t>(level, 1, 1, 1, 0.0f, memo, [] { return false; });
    EXPECT_EQ(memo.counts().kept, 27u);
    std::vector<std::uint8_t> fast(pages::kVoxels), slow(pages::kVoxels);
    pages::decodePage(level, 1, 1, 1, 0.0f, fast.data(), &memo);
    pages::decodePageByVoxel(level, 1, 1, 1, 0.0f, slow.data());
    EXPECT_EQ(fast, slow);
    EXPECT_EQ(memo.counts().kept, 27u);  // nothing decoded again
    EXPECT_EQ(memo.counts().found, 27u);
    // Helping and decoding at once, on two threads, over every page: the same pages.
    pages::BrickMemo shared = memoOfRoom();
    for (int p = 0; p < 27; ++p) {
      const int px = p % 3, py = p / 3 % 3, pz = p / 9;
      std::atomic<bool> there{false};
      std::thread helper([&] {
        pages::helpDecodePage<Level, std::uint8_t>(level, px, py, pz, 0.0f, shared,
                                                   [&] { return there.load(); });
      });
      pages::decodePage(level, px, py, pz, 0.0f, fast.data(), &shared);
      there = true;
      helper.join();
      pages::decodePageByVoxel(level, px, py, pz, 0.0f, slow.data());
      EXPECT_EQ(fast, slow) << "page " << px << "," << py << "," << pz;
    }
    EXPECT_EQ(shared.counts().replaced, 0u);
    EXPECT_EQ(shared.counts().kept, 125u);  // each brick kept once
  });
}

// Pages of big bricks decoded through a memo, in any order and from several threads at once, hold
// the values of the reference decode; with room for every brick each is decoded once (zfp's 16^3
// bricks: up to 27 under a page, 2^3 of them its own), and with room for one brick a shard, pages
// still decode alike while bricks are replaced.
TEST(PageDecode, PagesOfBigBricksDecodeEachBrickOnceThroughTheMemo) {
  withZfpPagedLevel([&](const auto& level) {
    using Level = std::remove_cvref_t<decltype(level)>;
    const std::uint64_t bricks = 5 * 5 * 5;  // of 16^3
    std::vector<int> order(27);
    for (int i = 0; i < 27; ++i) order[std::size_t(i)] = i;
    std::shuffle(order.begin(), order.end(), std::mt19937(5));
    for (const std::uint64_t room : {bricks, std::uint64_t(1)}) {
      // `room` a shard: with `bricks`, room for every brick however they fall in shards.
      pages::BrickMemo memo(Level::kVoxels, room * pages::BrickMemo::kShards * Level::kVoxels);
      ASSERT_TRUE(memo.usable());
      const auto work = [&](int first) {
        std::vector<std::uint8_t> fast(pages::kVoxels), slow(pages::kVoxels);
        for (int i = first; i < 27; i += 3) {
          const int p = order[std::size_t(i)], px = p % 3, py = p / 3 % 3, pz = p / 9;
          pages::decodePage(level, px, py, pz, 0.0f, fast.data(), &memo);
          pages::decodePageByVoxel(level, px, py, pz, 0.0f, slow.data());
          EXPECT_EQ(fast, slow) << "page " << px << "," << py << "," << pz;
        }
      };
      std::thread a(work, 0), b(work, 1);
      work(2);
      a.join(), b.join();
      const auto c = memo.counts();
      EXPECT_GT(c.found, 0u);
      if (room == bricks) {
        // Two threads may decode a brick at once; the memo keeps it once.
        EXPECT_EQ(c.kept, bricks);
        EXPECT_EQ(c.replaced, 0u);
      } else {
        EXPECT_GT(c.replaced, 0u);
      }
    }
  });
}
