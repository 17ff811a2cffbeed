// Writing one decoded page (page_cache.hpp: 32^3 voxels and an apron, clamped at the volume's
// faces) from a level of a compressed volume. These ways give the same values:
//
// - voxel by voxel, through the level's voxel(x, y, z, cache): any PageableLevel (svmm's coarse
//   level, a test's formula). Each voxel pays the view's brick lookup (the per-parity memo, the
//   thread's hashed brick cache) and a call: about 33 Mvox/s a core on vq.
// - a brick at a time, for the brick views (kernels::BrickView: vq, tvq, ksvd's levels, zfp):
//   every brick under the page is decoded once, a row of bricks in z at a time, straight from the
//   codec's decoder (no cache, no lookup per voxel; a brick whose key is the one before it in the
//   row is copied, not decoded again: the empty bricks of a codebook share one; ksvd's 8^3 bricks
//   the thread's last page decoded are copied from it; tvq's codevectors are asked of the memory
//   a few bricks ahead of their decode), and the page's rows are read out of that row through
//   per-axis offsets that do the faces' clamping.
// - the same through a memo of decoded bricks shared by the pages of the level (brick_memo.hpp),
//   for zfp's 16^3 bricks: a brick another page decoded is copied from the memo.
// - a base block at a time, for svmm's view (baseBlockSide(), baseBlock()): one walk down the
//   mip-map per block of the page, the same way.
//
// Values are stored as PageCache documents them: float(stored) + bias gives the voxel; integer
// pages round the decoded value and clamp it to the stored type.
#pragma once

#include <algorithm>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>
#include <voxwall/codec/kernels/cached_brick_view.hpp>
#include <voxwall/codec/kernels/trilinear.hpp>
#include <voxwall/codec/kernels/tvq_view.hpp>
#include <voxwall/node/brick_memo.hpp>

namespace voxwall::node::pages {

inline constexpr int kShift = 5;
inline constexpr int kSide = 1 << kShift;  // voxels per page side
inline constexpr int kRow = kSide + 3;     // with the apron: one voxel below, two above
inline constexpr int kVoxels = kRow * kRow * kRow;

// Where pages are cut. Page p holds the cells whose lower corner x lies in [32p - 15, 32p + 16]
// and stores voxels 32p - 16 .. 32p + 18 (its cells' corners and the apron a cell gradient
// reads: one voxel below, two above), so that a page's 35 voxels start on a multiple of 16. They
// then lie over 3 bricks of 16 a side (16, 16 and 3 voxels), 5 of 8 and 9 of 4, where pages cut
// at multiples of 32 (storing 32p - 1 .. 32p + 33: a voxel of the brick below, two of the brick
// above) lie over 4, 6 and 10. A brick codec decodes every brick under a page: 27 of zfp's bricks
// for a page instead of 64, 729 of vq's instead of 1000. The first page holds 17 cells, the last
// what remains.
inline constexpr int kLead = kSide / 2 - 1;
// The page of a cell's lower corner along one axis (0 <= i < the axis's voxels).
constexpr int pageOf(int i) { return (i + kLead) >> kShift; }
// The page's first stored voxel along one axis (below 0 at the volume's first face: clamped).
constexpr int firstVoxel(int page) { return page * kSide - kLead - 1; }
// Pages along an axis of `dim` voxels (dim >= 1).
constexpr int pagesAlong(int dim) { return pageOf(dim - 1) + 1; }

// The level of `view` whose voxels pages hold: what its pagedLevel() names (ksvd's level 0), or
// the view itself.
template <class View>
decltype(auto) pagedLevel(const View& view) {
  if constexpr (requires { view.pagedLevel(); })
    return view.pagedLevel();
  else
    return (view);
}

// A decoded value as stored in a page of type Stored (see above).
template <class Stored>
inline Stored store(float v, float bias) {
  if constexpr (std::is_same_v<Stored, float>) {
    return v;
  } else {
    const float hi = std::is_same_v<Stored, std::uint8_t> ? 255.0f : 65535.0f;
    const float s = std::nearbyint(v - bias);
    return Stored(s >= 0.0f ? (s <= hi ? s : hi) : 0.0f);
  }
}

// The reference: page (px, py, pz) of `level` into `out`, voxel by voxel.
template <class Level, class Stored>
void decodePageByVoxel(const Level& level, int px, int py, int pz, float bias, Stored* out) {
  typename Level::RayCache cache;
  for (int z = 0; z < kRow; ++z)
    for (int y = 0; y < kRow; ++y) {
      const int gz = codec::kernels::clampIndex(firstVoxel(pz) + z, level.dimZ);
      const int gy = codec::kernels::clampIndex(firstVoxel(py) + y, level.dimY);
      for (int x = 0; x < kRow; ++x) {
        const int gx = codec::kernels::clampIndex(firstVoxel(px) + x, level.dimX);
        *out++ = store<Stored>(level.voxel(gx, gy, gz, cache), bias);
      }
    }
}

// Where the page's voxels along one axis lie among the bricks of side `side`: the first brick,
// how many, and per page coordinate its brick (relative to the first) and its index within it.
struct PageAxis {
  int first = 0, count = 0;
  int brick[kRow], within[kRow];
  PageAxis(int page, int dim, int side) {
    for (int i = 0; i < kRow; ++i) {
      const int g = codec::kernels::clampIndex(firstVoxel(page) + i, dim);
      brick[i] = g / side, within[i] = g % side;
    }
    first = brick[0], count = brick[kRow - 1] - first + 1;
    for (int i = 0; i < kRow; ++i) brick[i] -= first;
  }
};

// Writes the page's voxels from one row of decoded bricks at a time: `row(bz, bricks)` fills the
// bricks of row bz (relative to az.first), brick (i, j) at (j * ax.count + i) * side^3, each x
// fastest; `put(value)` is a brick's value as the page stores it.
template <class Value, class Stored, class Row, class Put>
void writePageRows(int side, const PageAxis& ax, const PageAxis& ay, const PageAxis& az, Row row,
                   Put put, Stored* out) {
  const int brickVoxels = side * side * side;
  thread_local std::vector<Value> bricks;
  bricks.resize(std::size_t(ax.count) * std::size_t(ay.count) * std::size_t(brickVoxels));
  int offX[kRow], offY[kRow];
  for (int i = 0; i < kRow; ++i) {
    offX[i] = ax.brick[i] * brickVoxels + ax.within[i];
    offY[i] = ay.brick[i] * ax.count * brickVoxels + ay.within[i] * side;
  }
  int z = 0;
  for (int bz = 0; bz < az.count; ++bz) {
    row(bz, bricks.data());
    for (; z < kRow && az.brick[z] == bz; ++z) {
      const Value* slice = bricks.data() + az.within[z] * side * side;
      for (int y = 0; y < kRow; ++y) {
        const Value* line = slice + offY[y];
        for (int x = 0; x < kRow; ++x) *out++ = put(line[offX[x]]);
      }
    }
  }
}

// The cache lines a tvq brick's decode reads from its codevectors (host only), asked for ahead:
// the associated codebooks are megabytes (22631 lowpass codevectors of 256 bytes in the MRI
// template's file), and a page's bricks pick among them at random.
inline void prefetchBrick(const codec::kernels::TvqDecoder& d, std::uint64_t key) {
  std::uint32_t dc = 0;
  const float* v[codec::kernels::kTvqPartitions];
  if (!d.codevectors(key, dc, v)) return;
  for (int p = 0; p < d.partitions; ++p)
    for (int i = 0; i < d.kVoxels; i += 16) __builtin_prefetch(v[p] + i);  // 64-byte lines
}
inline constexpr int kPrefetchAhead = 8;
inline constexpr int kMaxRowBricks = (kRow / 4 + 2) * (kRow / 4 + 2);  // a row of bricks of >= 4^3

// Page (px, py, pz) of a brick view, a brick at a time (see above). Equals decodePageByVoxel.
template <codec::kernels::BrickView View, class Stored>
void decodePageByBrick(const View& view, int px, int py, int pz, float bias, Stored* out) {
  constexpr int S = View::kSide, kBrick = View::kVoxels;
  using Value = typename View::Value;
  const PageAxis ax(px, view.dimX, S), ay(py, view.dimY, S), az(pz, view.dimZ, S);
  // Big bricks (ksvd's 8^3; zfp's 16^3 where no memo is given): the apron reaches into bricks
  // the page beside it decodes too; the bricks of the last page this thread decoded are kept and
  // copied instead of decoded again (a ray's pages follow each other, and most of them share a
  // face). [0]: the last page's, [1]: this one's; for zfp 432 KiB each a thread.
  constexpr bool kKeep = kBrick >= 512;
  struct Kept {
    std::uint64_t id = 0;
    std::vector<std::uint64_t> keys;
    std::vector<Value> voxels;
  };
  thread_local Kept kept[2];
  if constexpr (kKeep) kept[1].id = view.cacheId, kept[1].keys.clear(), kept[1].voxels.clear();
  const auto decode = [&](std::uint64_t key, Value* at) {
    if constexpr (kKeep) {
      if (kept[0].id == view.cacheId)
        for (std::size_t i = 0; i < kept[0].keys.size(); ++i)
          if (kept[0].keys[i] == key) {
            const Value* from = kept[0].voxels.data() + i * kBrick;
            std::copy(from, from + kBrick, at);
            return;
          }
    }
    view.decoder.decode(key, at);
  };
  constexpr bool kPrefetch = requires { prefetchBrick(view.decoder, std::uint64_t(0)); };
  static_assert(!kPrefetch || S >= 4, "kMaxRowBricks counts bricks of at least 4 voxels a side");
  const auto row = [&](int bz, Value* at) {
    std::uint64_t last = ~std::uint64_t(0);
    const Value* lastBrick = nullptr;
    const auto brick = [&](std::uint64_t key) {
      if (key == last)
        std::copy(lastBrick, lastBrick + kBrick, at);
      else
        decode(key, at);
      last = key, lastBrick = at;
      if constexpr (kKeep) {
        kept[1].keys.push_back(key);
        kept[1].voxels.insert(kept[1].voxels.end(), at, at + kBrick);
      }
      at += kBrick;
    };
    if constexpr (kPrefetch) {
      std::uint64_t keys[kMaxRowBricks];
      int n = 0;
      for (int by = 0; by < ay.count; ++by)
        for (int bx = 0; bx < ax.count; ++bx)
          keys[n++] = view.decoder.key(ax.first + bx, ay.first + by, az.first + bz);
      for (int i = 0; i < std::min(n, kPrefetchAhead); ++i) prefetchBrick(view.decoder, keys[i]);
      for (int i = 0; i < n; ++i) {
        if (i + kPrefetchAhead < n) prefetchBrick(view.decoder, keys[i + kPrefetchAhead]);
        brick(keys[i]);
      }
    } else {
      for (int by = 0; by < ay.count; ++by)
        for (int bx = 0; bx < ax.count; ++bx)
          brick(view.decoder.key(ax.first + bx, ay.first + by, az.first + bz));
    }
  };
  writePageRows<Value>(
      S, ax, ay, az, row, [&](Value v) { return store<Stored>(view.decoder.scalar(v), bias); },
      out);
  if constexpr (kKeep) std::swap(kept[0], kept[1]);
}

// Whether pages of `Level` decode through a BrickMemo (brick_memo.hpp): brick views of bricks of
// 16^3 (zfp's): a page's 27 bricks hold 8 bricks' worth of its voxels, and the pages beside it
// decode the rest too. Smaller bricks decode in about what a lookup in the memo and a copy
// cost: with pages in a shuffled order, ksvd's 8^3 bricks gave 138 Mvox/s of pages without it
// and 132 with it, zfp's 16^3 25 and 98 (voxwall_bench_pages on one core, the MRI template of
// mricron-data as it is, compressed with --block 8 and zfp's defaults).
template <class Level>
constexpr bool sharesBricks() {
  if constexpr (codec::kernels::BrickView<Level>)
    return Level::kSide >= 16;
  else
    return false;
}

// Brick `key` decoded (into `decoded`), stored as a page stores it (into `out`) and kept in `memo`.
template <codec::kernels::BrickView View, class Stored>
void decodeBrickIntoMemo(const View& view, std::uint64_t key, float bias, BrickMemo& memo,
                         typename View::Value* decoded, Stored* out) {
  view.decoder.decode(key, decoded);
  for (int i = 0; i < View::kVoxels; ++i)
    out[i] = store<Stored>(view.decoder.scalar(decoded[i]), bias);
  memo.keep(key, out);
}

// Page (px, py, pz) of a brick view of big bricks, each brick taken from `memo` where another
// page kept it, else decoded, stored as the page stores it and kept. Equals decodePageByVoxel.
template <codec::kernels::BrickView View, class Stored>
void decodePageByMemo(const View& view, int px, int py, int pz, float bias, BrickMemo& memo,
                      Stored* out) {
  constexpr int S = View::kSide, kBrick = View::kVoxels;
  const PageAxis ax(px, view.dimX, S), ay(py, view.dimY, S), az(pz, view.dimZ, S);
  thread_local std::vector<typename View::Value> decoded;
  decoded.resize(kBrick);
  const auto row = [&](int bz, Stored* at) {
    std::uint64_t last = ~std::uint64_t(0);
    const Stored* lastBrick = nullptr;
    for (int by = 0; by < ay.count; ++by)
      for (int bx = 0; bx < ax.count; ++bx, at += kBrick) {
        const std::uint64_t key = view.decoder.key(ax.first + bx, ay.first + by, az.first + bz);
        if (key == last) {
          std::copy(lastBrick, lastBrick + kBrick, at);
        } else if (!memo.find(key, at)) {
          decodeBrickIntoMemo(view, key, bias, memo, decoded.data(), at);
        }
        last = key, lastBrick = at;
      }
  };
  writePageRows<Stored>(
      S, ax, ay, az, row, [](Stored v) { return v; }, out);
}

// What a thread does while another decodes page (px, py, pz) of a view of big bricks through
// `memo` (decodePageByMemo), instead of only waiting for it: decodes the page's bricks that the
// memo does not hold into it, last brick first, until `done()` (the page is there) or every
// brick is held. The decoding thread goes first brick first and copies what it finds in the
// memo, so the two meet about halfway; at most the brick where they meet is decoded twice.
template <codec::kernels::BrickView View, class Stored, class Done>
void helpDecodePage(const View& view, int px, int py, int pz, float bias, BrickMemo& memo,
                    Done&& done) {
  constexpr int S = View::kSide, kBrick = View::kVoxels;
  const PageAxis ax(px, view.dimX, S), ay(py, view.dimY, S), az(pz, view.dimZ, S);
  thread_local std::vector<typename View::Value> decoded;
  thread_local std::vector<Stored> stored;
  decoded.resize(kBrick), stored.resize(kBrick);
  for (int bz = az.count - 1; bz >= 0; --bz)
    for (int by = ay.count - 1; by >= 0; --by)
      for (int bx = ax.count - 1; bx >= 0; --bx) {
        if (done()) return;
        const std::uint64_t key = view.decoder.key(ax.first + bx, ay.first + by, az.first + bz);
        if (!memo.holds(key))
          decodeBrickIntoMemo(view, key, bias, memo, decoded.data(), stored.data());
      }
}

// Page (px, py, pz) of a view that reads its base blocks whole (svmm: baseBlockSide() > 0).
template <class View, class Stored>
void decodePageByBaseBlock(const View& view, int px, int py, int pz, float bias, Stored* out) {
  const int w = view.baseBlockSide(), blockVoxels = w * w * w;
  const PageAxis ax(px, view.dimX, w), ay(py, view.dimY, w), az(pz, view.dimZ, w);
  const auto row = [&](int bz, std::uint32_t* at) {
    for (int by = 0; by < ay.count; ++by)
      for (int bx = 0; bx < ax.count; ++bx, at += blockVoxels)
        view.baseBlock(ax.first + bx, ay.first + by, az.first + bz, at);
  };
  writePageRows<std::uint32_t>(
      w, ax, ay, az, row, [&](std::uint32_t v) { return store<Stored>(view.scalar(v), bias); },
      out);
}

// Page (px, py, pz) of `level`: a brick at a time where it is a brick view (through `memo` where
// it has big bricks and one is given), a base block at a time where it reads them whole (svmm),
// else voxel by voxel.
template <class Level, class Stored>
void decodePage(const Level& level, int px, int py, int pz, float bias, Stored* out,
                BrickMemo* memo = nullptr) {
  if constexpr (sharesBricks<Level>()) {
    if (memo && memo->usable()) {
      decodePageByMemo(level, px, py, pz, bias, *memo, out);
      return;
    }
  }
  if constexpr (codec::kernels::BrickView<Level>) {
    decodePageByBrick(level, px, py, pz, bias, out);
    return;
  } else if constexpr (requires(std::uint32_t * at) {
                         { level.baseBlockSide() } -> std::convertible_to<int>;
                         level.baseBlock(0, 0, 0, at);
                       }) {
    if (level.baseBlockSide() > 0) {
      decodePageByBaseBlock(level, px, py, pz, bias, out);
      return;
    }
  }
  decodePageByVoxel(level, px, py, pz, bias, out);
}

}  // namespace voxwall::node::pages
