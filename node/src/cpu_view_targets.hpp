// The CPU raycaster of the view types of one unit (VOXWALL_VIEW_UNIT, view_units.hpp), once per
// SIMD target: Highway's
// foreach_target.h includes this file again for each instruction set the build targets
// (HWY_TARGETS, set in node/CMakeLists.txt), and HWY_DYNAMIC_DISPATCH calls the best one the CPU
// running it supports. No include guard, by design.
//
// On a SIMD target a packet of neighbouring rays (4x4 pixels with 16 lanes, 4x2 with 8) runs the
// per-ray code of LaneKernels::raycastLanes (kernels/raycast_lanes.inl, compiled here for each
// target) through HwyLanes: a lane per ray, a mask for the rays still going. The view's own sample,
// gradient and traversal hooks run per lane (each ray keeps its view cache); ray setup, skipping,
// the transfer function, shading and compositing run on whole vectors.
// The loop over a tile's blocks that runs the packets is cpu_packet_blocks.inl, included below
// inside the same target region.
#include <hwy/highway.h>
// Highway's vector exp (per target, like this file).
#include <hwy/contrib/math/math-inl.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <voxwall/node/kernels/raycast.hpp>

#include "cpu_blocks_impl.hpp"

HWY_BEFORE_NAMESPACE();
namespace voxwall::node::cpu {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

#if HWY_TARGET != HWY_EMU128 && HWY_TARGET != HWY_SCALAR
#define VOXWALL_PACKETS 1
#else
#define VOXWALL_PACKETS 0
#endif

#if VOXWALL_PACKETS
// The code over lanes and over corner values, compiled again for this target (raycast_lanes.inl
// says why): LaneKernels (the ray march) and Corners (the trilinear blend and differences).
using kernels::Lanes3, kernels::Lanes4, kernels::RayFrame, kernels::SkipGrid, kernels::TransferLut;
#include <voxwall/codec/kernels/corners.inl>
#include <voxwall/node/kernels/raycast_lanes.inl>

template <class V>
inline constexpr bool kRaw = false;
template <class T>
inline constexpr bool kRaw<codec::kernels::RawView<T>> = true;

// LaneKernels::raycastLanes' lane policy (see kernels::ScalarLanes) over Highway vectors of floats
// and int32.
struct HwyLanes {
  using D = hn::ScalableTag<float>;
  using DI = hn::RebindToSigned<D>;
  using DU = hn::RebindToUnsigned<D>;
  using F = hn::Vec<D>;
  using I = hn::Vec<DI>;
  using M = hn::Mask<D>;
  static constexpr std::size_t kLanes = hn::MaxLanes(D());
  static_assert(kLanes >= 4 && kLanes <= 64 && (kLanes & (kLanes - 1)) == 0);
  template <class View>
  struct Caches {
    typename View::RayCache lane[kLanes];  // the view's own, one per ray
    F c[8];    // the corners of the last sample of a view sampled on vectors (raw, pages)
    I pageAt;  // decoded pages: the pool offset of the last sample's cell, where `paged`
    M paged;
    // The block's hold on the backend's decoded pages (null: none), and each lane's last page
    // plus one (0: none yet; an array, so that no vector op runs outside the target's code).
    PageCache::Reader* reader = currentReader;
    std::int32_t lastPage1[kLanes] = {};
    // Lanes whose page was not resident under pressure (PageCache::Reader::fillIfRoom): this step
    // they sample level 1, from its pages (`lower`) where the backend has them, else through the
    // view with a footprint that selects it (their own kept here).
    // (No vector op in these initialisers: they may run outside the target's code.)
    M coarse;                      // set in every step before it is read
    std::uint64_t raisedBits = 0;  // lanes whose footprint was raised for the last step
    float footprint[kLanes] = {};
    bool footprints = false;  // a footprint was given (setFootprint: --lod): else every lane's is 0
    // Level 1's pages, under pressure (views with levels): the same state as above for them.
    struct Lower {
      PageCache::Reader* reader = currentCoarseReader;
      F c[8];
      I pageAt;
      M paged;  // set in every step before it is read, as coarse
      M coarse;
      std::int32_t lastPage1[kLanes] = {};
    } lower;
  };

  static HWY_INLINE F splat(float v) { return hn::Set(D(), v); }
  static HWY_INLINE I splatI(int v) { return hn::Set(DI(), v); }
  static HWY_INLINE F select(M m, F a, F b) { return hn::IfThenElse(m, a, b); }
  static HWY_INLINE I selectI(M m, I a, I b) {
    return hn::IfThenElse(hn::RebindMask(DI(), m), a, b);
  }
  static HWY_INLINE M selectM(M m, M a, M b) { return hn::Or(hn::And(m, a), hn::AndNot(m, b)); }
  static HWY_INLINE M both(M a, M b) { return hn::And(a, b); }
  static HWY_INLINE M either(M a, M b) { return hn::Or(a, b); }
  static HWY_INLINE M butNot(M a, M b) { return hn::AndNot(b, a); }
  static HWY_INLINE bool any(M m) { return !hn::AllFalse(D(), m); }
  static HWY_INLINE M lessI(I a, I b) { return hn::RebindMask(D(), a < b); }
  static HWY_INLINE M isZeroI(I a) { return hn::RebindMask(D(), a == hn::Zero(DI())); }
  static HWY_INLINE F sqrt(F v) { return hn::Sqrt(v); }
  static HWY_INLINE F abs(F v) { return hn::Abs(v); }
  static HWY_INLINE I trunc(F v) { return hn::ConvertTo(DI(), v); }
  static HWY_INLINE F toFloat(I v) { return hn::ConvertTo(D(), v); }
  static HWY_INLINE I shiftRight(I v, int s) { return hn::ShiftRightSame(v, s); }
  static HWY_INLINE I ceilInt(F v) {
    const I i = trunc(v);
    return i + selectI(v > toFloat(i), splatI(1), splatI(0));
  }

  // The lanes of m as bits, lane 0 lowest.
  static HWY_INLINE std::uint64_t bits(M m) {
    std::uint8_t b[8] = {};
    hn::StoreMaskBits(D(), m, b);
    std::uint64_t v;
    std::memcpy(&v, b, sizeof v);
    return v;
  }
  // Calls fn(lane) for each lane set in m.
  template <class Fn>
  static HWY_INLINE void forLanes(M m, const Fn& fn) {
    for (std::uint64_t b = bits(m); b; b &= b - 1) fn(std::size_t(std::countr_zero(b)));
  }

  // Within a few ULP of expf (pre-integrated opacities).
  static HWY_INLINE F exp(F v) { return hn::Exp(D(), v); }
  static HWY_INLINE F pow(F v, float e) {
    HWY_ALIGN float x[kLanes];
    hn::Store(v, D(), x);
    for (std::size_t i = 0; i < kLanes; ++i) x[i] = powf(x[i], e);
    return hn::Load(D(), x);
  }

  // Where m: is base[index] non-zero (a skip grid's cell)? Other lanes read byte 0.
  static HWY_INLINE M byteSet(const std::uint8_t* base, I index, M m) {
    return both(m, gather(base, selectI(m, index, splatI(0))) != hn::Zero(D()));
  }
  // Where m: is bit `index` of the words set (bit index % 32 of word index / 32)? Other lanes
  // read word 0.
  static HWY_INLINE M bitSet(const std::uint32_t* words, I index, M m) {
    const I at = selectI(m, index, splatI(0));
    const auto word = hn::BitCast(
        DU(),
        hn::GatherIndex(DI(), reinterpret_cast<const std::int32_t*>(words), hn::ShiftRight<5>(at)));
    const auto bit =
        hn::And(hn::Shr(word, hn::BitCast(DU(), hn::And(at, splatI(31)))), hn::Set(DU(), 1u));
    return both(m, hn::RebindMask(D(), bit != hn::Zero(DU())));
  }

  static HWY_INLINE kernels::Lanes4<F> lookup(const kernels::TransferLut& lut, F value) {
    // Clamped as TransferLut::lookup does (Max and Min also take a NaN to 0).
    F f = (value - splat(lut.lo)) * splat(lut.scale);
    f = hn::Min(hn::Max(f, hn::Zero(D())), splat(lut.last));
    const I i = trunc(f);
    const F t = f - toFloat(i);
    const float* base = reinterpret_cast<const float*>(lut.entries);
    const I at = hn::ShiftLeft<2>(i);
    auto channel = [&](int c) {
      const F a = hn::GatherIndex(D(), base + c, at), b = hn::GatherIndex(D(), base + 4 + c, at);
      return a + t * (b - a);
    };
    return {channel(0), channel(1), channel(2), channel(3)};
  }

  // RawView sampled on whole vectors: the corners gathered from the bricks in one go per
  // corner. Needs element offsets below 2^31 bytes (else the view runs per lane).
  template <class T>
  static HWY_INLINE bool gathers(const codec::kernels::RawView<T>& v) {
    const std::uint64_t bricksZ =
        (std::uint64_t(v.dimZ) + std::uint64_t(v.mask)) >> unsigned(v.brickShift);
    return reinterpret_cast<std::uintptr_t>(v.bricks) % alignof(T) == 0 &&
           v.brickStrideZ * bricksZ * sizeof(T) + 8 < (std::uint64_t(1) << 31);
  }
  // base[index] per lane, as floats. Narrow types are gathered as the aligned 32-bit words that
  // hold them (readable wherever the element is) and shifted out.
  template <class T>
  static HWY_INLINE F gather(const T* base, I index) {
    if constexpr (std::is_same_v<T, float>) {
      return hn::GatherIndex(D(), base, index);
    } else {
      static_assert(sizeof(T) == 1 || sizeof(T) == 2);
      const std::uintptr_t address = reinterpret_cast<std::uintptr_t>(base);
      const auto* words = reinterpret_cast<const std::int32_t*>(address & ~std::uintptr_t(3));
      const I at = hn::ShiftLeft < sizeof(T) == 2 ? 1 : 0 > (index) + splatI(int(address & 3));
      const auto word = hn::BitCast(DU(), hn::GatherIndex(DI(), words, hn::ShiftRight<2>(at)));
      const auto shift = hn::BitCast(DU(), hn::ShiftLeft<3>(hn::And(at, splatI(3))));
      const I bitsOf = hn::BitCast(DI(), hn::Shr(word, shift));
      if constexpr (std::is_same_v<T, std::int16_t>)
        return toFloat(hn::ShiftRight<16>(hn::ShiftLeft<16>(bitsOf)));
      else
        return toFloat(hn::And(bitsOf, splatI(sizeof(T) == 1 ? 0xFF : 0xFFFF)));
    }
  }
  // The clamped position RawView::sample takes (Max and Min also take a NaN to 0).
  static HWY_INLINE F clampTo(F p, float hi) {
    return hn::Min(hn::Max(p, hn::Zero(D())), splat(hi));
  }
  template <class T, class Cache>
  static HWY_INLINE F rawSample(const codec::kernels::RawView<T>& v, Cache& cache,
                                const kernels::Lanes3<F>& p) {
    const F x = clampTo(p.x, v.maxX), y = clampTo(p.y, v.maxY), z = clampTo(p.z, v.maxZ);
    const I ix = trunc(x), iy = trunc(y), iz = trunc(z);
    const I s = splatI(v.mask);
    const I o = hn::ShiftRightSame(ix, v.brickShift) * splatI(int(v.brickStrideX)) +
                hn::ShiftRightSame(iy, v.brickShift) * splatI(int(v.brickStrideY)) +
                hn::ShiftRightSame(iz, v.brickShift) * splatI(int(v.brickStrideZ)) +
                hn::And(ix, s) + hn::And(iy, s) * splatI(v.rowStride) +
                hn::And(iz, s) * splatI(v.sliceStride);
    const I dy = splatI(v.rowStride), dz = splatI(v.sliceStride), dx = splatI(1);
    F* c = cache.c;  // corner (ix + 1, ...) is in the brick's apron
    c[0] = gather(v.bricks, o), c[1] = gather(v.bricks, o + dx);
    c[2] = gather(v.bricks, o + dy), c[3] = gather(v.bricks, o + dy + dx);
    c[4] = gather(v.bricks, o + dz), c[5] = gather(v.bricks, o + dz + dx);
    c[6] = gather(v.bricks, o + dz + dy), c[7] = gather(v.bricks, o + dz + dy + dx);
    return Corners::blend(c, x - toFloat(ix), y - toFloat(iy), z - toFloat(iz));
  }
  // The cell gradient from a cell's corners c and its 24 neighbours at(dx, dy, dz), at the
  // sample's offsets t in the cell, in world units (kernels::sampleGradient's scale).
  template <class At>
  static HWY_INLINE kernels::Lanes3<F> cellGradient(const F* c, const At& at,
                                                    const kernels::RayFrame& f, F tx, F ty, F tz) {
    F d[24];
    Corners::differences(c, at, d);
    return {Corners::blend(d, tx, ty, tz) * splat(0.5f * f.invSpacing.x),
            Corners::blend(d + 8, tx, ty, tz) * splat(0.5f * f.invSpacing.y),
            Corners::blend(d + 16, tx, ty, tz) * splat(0.5f * f.invSpacing.z)};
  }
  // RawView's cell gradient (cornerDifferences over the 24 voxels around the cell, clamped to
  // the volume) on vectors, right after rawSample at the same positions.
  template <class T, class Cache>
  static HWY_INLINE kernels::Lanes3<F> rawGradient(const codec::kernels::RawView<T>& v,
                                                   Cache& cache, const kernels::RayFrame& f,
                                                   const kernels::Lanes3<F>& p) {
    const F x = clampTo(p.x, v.maxX), y = clampTo(p.y, v.maxY), z = clampTo(p.z, v.maxZ);
    const I ix = trunc(x), iy = trunc(y), iz = trunc(z);
    const I s = splatI(v.mask);
    // Offsets -1 .. 2 along each axis, clamped, as their part of the element offset.
    I ox[4], oy[4], oz[4];
    for (int a = 0; a < 4; ++a) {
      auto clampAxis = [&](const I& i, int dim) {
        return hn::Min(hn::Max(i + splatI(a - 1), splatI(0)), splatI(dim - 1));
      };
      const I qx = clampAxis(ix, v.dimX), qy = clampAxis(iy, v.dimY), qz = clampAxis(iz, v.dimZ);
      ox[a] = hn::ShiftRightSame(qx, v.brickShift) * splatI(int(v.brickStrideX)) + hn::And(qx, s);
      oy[a] = hn::ShiftRightSame(qy, v.brickShift) * splatI(int(v.brickStrideY)) +
              hn::And(qy, s) * splatI(v.rowStride);
      oz[a] = hn::ShiftRightSame(qz, v.brickShift) * splatI(int(v.brickStrideZ)) +
              hn::And(qz, s) * splatI(v.sliceStride);
    }
    auto at = [&](int dx, int dy, int dz) {
      return gather(v.bricks, ox[dx + 1] + oy[dy + 1] + oz[dz + 1]);
    };
    return cellGradient(cache.c, at, f, x - toFloat(ix), y - toFloat(iy), z - toFloat(iz));
  }

  // A brick-coded level sampled from its decoded pages where m, on vectors: one gather in the
  // page table, the pages a lane misses decoded at once (Reader::fill), then the eight corners
  // gathered from the page as from a raw brick. Sets cache.paged to m and cache.pageAt, cache.c
  // for the gradient.
  //
  // The pool as an array of its stored type: fn(const Stored*).
  template <class Fn>
  static HWY_INLINE auto withPool(const PageCache& pages, const Fn& fn) {
    switch (pages.format()) {
      case PageFormat::UInt8:
        return fn(static_cast<const std::uint8_t*>(pages.pool()));
      case PageFormat::UInt16:
        return fn(static_cast<const std::uint16_t*>(pages.pool()));
      default:
        return fn(static_cast<const float*>(pages.pool()));
    }
  }
  // A stored value as the voxel: the bias of 16-bit pages (int16 data) added.
  template <class Stored>
  static HWY_INLINE F pageValue(const PageCache& pages, const Stored* pool, I o) {
    if constexpr (std::is_same_v<Stored, std::uint16_t>)
      return gather(pool, o) + splat(pages.bias());
    else
      return gather(pool, o);
  }
  // The eight corners of the cells at pool offsets o (corner i: bit 0 x + 1, bit 1 y + 1,
  // bit 2 z + 1), as the floats the view samples.
  template <class Stored>
  static HWY_INLINE void pageCorners(const PageCache& pages, const Stored* pool, I o, F* c) {
    using P = PageCache;
    for (int i = 0; i < 8; ++i)
      c[i] = pageValue(pages, pool,
                       o + splatI((i & 1) + ((i >> 1) & 1) * P::kRow + (i >> 2) * P::kSlice));
  }
  //
  // Under pressure, lanes whose page is neither resident nor decodable without evicting are left
  // out of cache.paged and set in cache.coarse (their value here is 0): the caller samples them
  // from a coarser level.
  template <class Level, class Cache>
  static HWY_INLINE F pageSample(const Level& v, Cache& cache, const kernels::Lanes3<F>& p, M m,
                                 bool pressure) {
    using P = PageCache;
    P::Reader& reader = *cache.reader;
    P& pages = reader.cache();
    reader.quiesce();  // the last step's page offsets are no longer used
    const F x = clampTo(p.x, v.maxX), y = clampTo(p.y, v.maxY), z = clampTo(p.z, v.maxZ);
    const I ix = trunc(x), iy = trunc(y), iz = trunc(z);
    // Offset by kLead: pages are cut so that their stored voxels start on a multiple of 16.
    const I lead = splatI(P::kLead);
    const I jx = ix + lead, jy = iy + lead, jz = iz + lead;
    const I page =
        (hn::ShiftRight<P::kShift>(jz) * splatI(pages.pagesY) + hn::ShiftRight<P::kShift>(jy)) *
            splatI(pages.pagesX) +
        hn::ShiftRight<P::kShift>(jx);
    I slot = hn::GatherIndex(DI(), pages.table(), selectI(m, page, splatI(0)));
    // Entries are published with a release store after their page is written.
    std::atomic_thread_fence(std::memory_order_acquire);
    const M miss = both(m, lessI(slot, splatI(0)));
    const I page1 = page + splatI(1), last1 = hn::LoadU(DI(), cache.lastPage1);
    const M entered = both(m, hn::RebindMask(D(), page1 != last1));
    const std::size_t missed = hn::CountTrue(D(), miss);
    reader.missed += missed;
    reader.hits += hn::CountTrue(D(), m) - missed;
    cache.coarse = hn::FirstN(D(), 0);
    if (any(either(miss, entered))) {
      HWY_ALIGN std::int32_t s[kLanes], at[kLanes];
      hn::Store(slot, DI(), s), hn::Store(page, DI(), at);
      if (pressure)
        forLanes(miss, [&](std::size_t i) { s[i] = reader.fillIfRoom(at[i], v); });
      else
        forLanes(miss, [&](std::size_t i) { s[i] = reader.fill(at[i], v, int(i)); });
      forLanes(entered, [&](std::size_t i) { pages.touch(at[i]); });
      slot = hn::Load(DI(), s);
      hn::StoreU(selectI(m, page1, last1), DI(), cache.lastPage1);
      if (pressure) {
        cache.coarse = both(miss, lessI(slot, splatI(0)));
        reader.coarse += hn::CountTrue(D(), cache.coarse);
        m = butNot(m, cache.coarse);
      }
    }
    cache.paged = m;
    const I low = splatI(P::kSide - 1), one = splatI(1);
    const I o = selectI(m, slot, splatI(0)) + (hn::And(jx, low) + one) +
                (hn::And(jy, low) + one) * splatI(P::kRow) +
                (hn::And(jz, low) + one) * splatI(P::kSlice);
    cache.pageAt = o;
    withPool(pages, [&](const auto* pool) { pageCorners(pages, pool, o, cache.c); });
    return Corners::blend(cache.c, x - toFloat(ix), y - toFloat(iy), z - toFloat(iz));
  }
  // The cell gradient of the lanes pageSample served, from the same page (its apron holds the
  // cell's 24 neighbours, clamped at the volume's faces as the view clamps them).
  template <class Level, class Cache>
  static HWY_INLINE kernels::Lanes3<F> pageGradient(const Level& v, Cache& cache,
                                                    const kernels::RayFrame& f,
                                                    const kernels::Lanes3<F>& p) {
    using P = PageCache;
    const P& pages = cache.reader->cache();
    const F x = clampTo(p.x, v.maxX), y = clampTo(p.y, v.maxY), z = clampTo(p.z, v.maxZ);
    const I ix = trunc(x), iy = trunc(y), iz = trunc(z);
    const I o = cache.pageAt;
    return withPool(pages, [&](const auto* pool) {
      auto at = [&](int dx, int dy, int dz) {
        return pageValue(pages, pool, o + splatI(dx + dy * P::kRow + dz * P::kSlice));
      };
      return cellGradient(cache.c, at, f, x - toFloat(ix), y - toFloat(iy), z - toFloat(iz));
    });
  }
  // The six-sample gradient (kernels::sampleGradient without the cell hook) of the lanes
  // pageSample served, from the same page: a sample one voxel away along an axis, with its
  // position clamped as the views clamp it, reads a cell whose corners lie in the page's apron.
  template <class Level, class Cache>
  static HWY_INLINE kernels::Lanes3<F> pageSixSamples(const Level& v, Cache& cache,
                                                      const kernels::RayFrame& f,
                                                      const kernels::Lanes3<F>& p) {
    using P = PageCache;
    const P& pages = cache.reader->cache();
    const I low = splatI(P::kSide - 1), one = splatI(1);
    // The sample's page: its slot and first voxel, from the sample's cell.
    const I ix = trunc(clampTo(p.x, v.maxX)), iy = trunc(clampTo(p.y, v.maxY)),
            iz = trunc(clampTo(p.z, v.maxZ));
    const I lead = splatI(P::kLead);  // as pageSample cuts pages
    const I lx = hn::And(ix + lead, low), ly = hn::And(iy + lead, low),
            lz = hn::And(iz + lead, low);
    const I slot =
        cache.pageAt - (lx + one) - (ly + one) * splatI(P::kRow) - (lz + one) * splatI(P::kSlice);
    const I bx = ix - lx, by = iy - ly, bz = iz - lz;
    return withPool(pages, [&](const auto* pool) {
      auto at = [&](F qx, F qy, F qz) {
        qx = clampTo(qx, v.maxX), qy = clampTo(qy, v.maxY), qz = clampTo(qz, v.maxZ);
        const I jx = trunc(qx), jy = trunc(qy), jz = trunc(qz);
        const I o = slot + (jx - bx + one) + (jy - by + one) * splatI(P::kRow) +
                    (jz - bz + one) * splatI(P::kSlice);
        F c[8];
        pageCorners(pages, pool, o, c);
        return Corners::blend(c, qx - toFloat(jx), qy - toFloat(jy), qz - toFloat(jz));
      };
      const F d = splat(1.0f);
      return kernels::Lanes3<F>{
          (at(p.x + d, p.y, p.z) - at(p.x - d, p.y, p.z)) * splat(0.5f * f.invSpacing.x),
          (at(p.x, p.y + d, p.z) - at(p.x, p.y - d, p.z)) * splat(0.5f * f.invSpacing.y),
          (at(p.x, p.y, p.z + d) - at(p.x, p.y, p.z - d)) * splat(0.5f * f.invSpacing.z)};
    });
  }
  // The lanes of m whose sample reads the paged level: all for a brick view; for a view with
  // levels (ksvd, svmm) those whose footprint picks the full-resolution level, with trilinear
  // sampling (the views' sample()).
  template <class View>
  static HWY_INLINE M pageLanes(const View& view, const Caches<View>& cache, M m) {
    if constexpr (requires { View::kTraversal; }) {
      if (cache.lane[0].nearest) return hn::FirstN(D(), 0);  // set alike in every lane
      if (!cache.footprints) return m;  // every footprint 0: the full-resolution level
      HWY_ALIGN std::int32_t level0[kLanes];
      for (std::size_t i = 0; i < kLanes; ++i) {
        const float footprint = cache.lane[i].footprint;
        level0[i] = footprint >= 2.0f && view.lodLevel(footprint) != 0 ? 0 : -1;
      }
      return both(m, hn::RebindMask(D(), hn::Load(DI(), level0) != hn::Zero(DI())));
    } else {
      (void)view, (void)cache;
      return m;
    }
  }
  // A full-resolution index-space position on the grid of a level whose voxels span `scale`.
  static HWY_INLINE kernels::Lanes3<F> toCoarse(const kernels::Lanes3<F>& p, float scale) {
    const F half = splat(0.5f), inv = splat(1.0f / scale);
    return {(p.x + half) * inv - half, (p.y + half) * inv - half, (p.z + half) * inv - half};
  }
  // Both inside [0, dim - 1] on every axis (else the view's gradient takes six samples).
  template <class Level>
  static HWY_INLINE M insideGrid(const Level& v, const kernels::Lanes3<F>& p) {
    const F zero = hn::Zero(D());
    return both(both(both(p.x >= zero, p.y >= zero), both(p.z >= zero, p.x <= splat(v.maxX))),
                both(p.y <= splat(v.maxY), p.z <= splat(v.maxZ)));
  }

  // The view's hooks where m: on vectors for RawView and for lanes on decoded pages, else per
  // lane (each ray its own cache).
  template <class View>
  static HWY_INLINE F sample(const View& view, Caches<View>& cache, const kernels::Lanes3<F>& p,
                             M m) {
    if constexpr (kRaw<View>) {
      if (gathers(view)) return rawSample(view, cache, p);
    }
    HWY_ALIGN float x[kLanes], y[kLanes], z[kLanes], out[kLanes] = {};
    if constexpr (kPaged<View>) {
      const auto& level = pagedLevel(view);
      cache.paged = hn::FirstN(D(), 0);
      cache.lower.paged = hn::FirstN(D(), 0);
      if (cache.reader) {
        constexpr bool levels = requires { View::kTraversal; };
        // Last step's coarse lanes take their own footprint back.
        if constexpr (kLevels<View>)
          for (std::uint64_t b = cache.raisedBits; b; b &= b - 1) {
            const std::size_t i = std::size_t(std::countr_zero(b));
            cache.lane[i].footprint = cache.footprint[i];
          }
        cache.raisedBits = 0;
        cache.coarse = hn::FirstN(D(), 0);
        // (No page offset of level 1 is held between steps either.)
        if (cache.lower.reader) cache.lower.reader->quiesce();
        const M lanes = pageLanes(view, cache, m);
        if (any(lanes)) {
          F value = pageSample(level, cache, p, lanes, levels && cache.reader->pressure());
          if constexpr (kLevels<View>) {
            // Lanes under pressure sample level 1 from its own pages, gathered as level 0's.
            if (cache.lower.reader && any(cache.coarse)) {
              const float s = coarseScale(view);
              const F v =
                  pageSample(coarseLevel(view), cache.lower, toCoarse(p, s), cache.coarse, false);
              value = select(cache.coarse, v, value);
              m = butNot(m, cache.coarse);
              cache.coarse = hn::FirstN(D(), 0);
            }
          }
          // Lanes under pressure without those pages sample (and shade, and skip regions of)
          // level 1 through the view for this step: the footprint of its voxels.
          if constexpr (kLevels<View>) {
            forLanes(cache.coarse, [&](std::size_t i) {
              cache.footprint[i] = cache.lane[i].footprint;
              cache.lane[i].footprint = std::max(cache.lane[i].footprint, coarseScale(view));
            });
            cache.raisedBits = bits(cache.coarse);
          }
          m = butNot(m, cache.paged);  // the rest decode through the view's caches
          if (!any(m)) return value;
          hn::Store(value, D(), out);
        }
      }
    }
    hn::Store(p.x, D(), x), hn::Store(p.y, D(), y), hn::Store(p.z, D(), z);
    forLanes(m, [&](std::size_t i) { out[i] = view.sample(x[i], y[i], z[i], cache.lane[i]); });
    return hn::Load(D(), out);
  }
  template <class View>
  static HWY_INLINE kernels::Lanes3<F> gradient(const View& view, Caches<View>& cache,
                                                const kernels::RayFrame& f,
                                                const kernels::Lanes3<F>& p, M m) {
    kernels::Lanes3<F> vectors{hn::Zero(D()), hn::Zero(D()), hn::Zero(D())};
    if constexpr (kRaw<View>) {
      if (f.cellGradients && gathers(view)) {
        // The volume's outer half voxel takes the six samples (outsideGrid), per lane below.
        const F zero = hn::Zero(D());
        const M inner =
            both(both(both(p.x >= zero, p.y >= zero), both(p.z >= zero, p.x <= splat(view.maxX))),
                 both(p.y <= splat(view.maxY), p.z <= splat(view.maxZ)));
        vectors = rawGradient(view, cache, f, p);
        m = butNot(m, inner);
        if (!any(m)) return vectors;
      }
    }
    if constexpr (kPaged<View>) {
      // Lanes sampled from pages take their gradient from the same page: the cell gradient
      // inside the grid, else (the outer half voxel, --gradients samples) the six samples.
      const auto& level = pagedLevel(view);
      const M paged = both(m, cache.paged);
      if (cache.reader && any(paged)) {
        const M cell = f.cellGradients ? both(paged, insideGrid(level, p)) : hn::FirstN(D(), 0);
        const M six = butNot(paged, cell);
        if (any(cell)) vectors = pageGradient(level, cache, f, p);
        if (any(six)) {
          const kernels::Lanes3<F> g = pageSixSamples(level, cache, f, p);
          vectors = {select(six, g.x, vectors.x), select(six, g.y, vectors.y),
                     select(six, g.z, vectors.z)};
        }
        m = butNot(m, paged);
        if (!any(m)) return vectors;
      }
    }
    if constexpr (kLevels<View>) {
      // Lanes sampled from level 1's pages: their gradient from the same pages, in level-1 index
      // units, scaled to the volume's.
      const M lower = both(m, cache.lower.paged);
      if (cache.lower.reader && any(lower)) {
        const float s = coarseScale(view);
        const auto& level = coarseLevel(view);
        const kernels::Lanes3<F> q = toCoarse(p, s);
        kernels::RayFrame fl = f;
        fl.invSpacing = f.invSpacing / s;
        const M cell = f.cellGradients ? both(lower, insideGrid(level, q)) : hn::FirstN(D(), 0);
        const M six = butNot(lower, cell);
        kernels::Lanes3<F> g = vectors;
        if (any(cell)) g = pageGradient(level, cache.lower, fl, q);
        if (any(six)) {
          const kernels::Lanes3<F> g6 = pageSixSamples(level, cache.lower, fl, q);
          g = {select(six, g6.x, g.x), select(six, g6.y, g.y), select(six, g6.z, g.z)};
        }
        vectors = {select(lower, g.x, vectors.x), select(lower, g.y, vectors.y),
                   select(lower, g.z, vectors.z)};
        m = butNot(m, lower);
        if (!any(m)) return vectors;
      }
    }
    HWY_ALIGN float x[kLanes], y[kLanes], z[kLanes], gx[kLanes], gy[kLanes], gz[kLanes];
    hn::Store(p.x, D(), x), hn::Store(p.y, D(), y), hn::Store(p.z, D(), z);
    hn::Store(vectors.x, D(), gx), hn::Store(vectors.y, D(), gy), hn::Store(vectors.z, D(), gz);
    forLanes(m, [&](std::size_t i) {
      const glm::vec3 g =
          kernels::sampleGradient(view, cache.lane[i], f, glm::vec3(x[i], y[i], z[i]));
      gx[i] = g.x, gy[i] = g.y, gz[i] = g.z;
    });
    return {hn::Load(D(), gx), hn::Load(D(), gy), hn::Load(D(), gz)};
  }
  template <class View>
  static HWY_INLINE void setNearest(Caches<View>& cache, bool nearest) {
    for (auto& c : cache.lane) c.nearest = nearest;
  }
  template <class View>
  static HWY_INLINE void setFootprint(Caches<View>& cache, F footprint, M m) {
    HWY_ALIGN float v[kLanes];
    hn::Store(footprint, D(), v);
    forLanes(m, [&](std::size_t i) { cache.lane[i].footprint = v[i]; });
    cache.raisedBits &= ~bits(m);  // their own footprint is set anew
    cache.footprints = true;
  }
  template <class View>
  static HWY_INLINE I regionEnd(const Caches<View>& cache, const glm::vec3& o,
                                const kernels::Lanes3<F>& invD, const kernels::RayFrame& f,
                                F tEnter, float invStep, I steps, I k, M m) {
    // A lane sampled from pages knows no region: it takes the next sample.
    if constexpr (kPaged<View>) {
      m = butNot(m, either(cache.paged, cache.lower.paged));
      if (!any(m)) return k + splatI(1);
    }
    HWY_ALIGN float ix[kLanes], iy[kLanes], iz[kLanes], te[kLanes];
    HWY_ALIGN std::int32_t st[kLanes], kk[kLanes], out[kLanes];
    hn::Store(invD.x, D(), ix), hn::Store(invD.y, D(), iy), hn::Store(invD.z, D(), iz);
    hn::Store(tEnter, D(), te), hn::Store(steps, DI(), st), hn::Store(k, DI(), kk);
    hn::Store(k + splatI(1), DI(), out);
    forLanes(m, [&](std::size_t i) {
      out[i] = kernels::regionEnd(cache.lane[i], o, glm::vec3(ix[i], iy[i], iz[i]), f, te[i],
                                  invStep, st[i], kk[i]);
    });
    return hn::Load(DI(), out);
  }
};

#include "cpu_packet_blocks.inl"  // renderPacketBlocks: the packet loop over blocks
#endif                            // VOXWALL_PACKETS

template <class View>
std::uint64_t renderViewBlocks(const View& view, const TileJob& job) {
#if VOXWALL_PACKETS
  if (job.packets) return renderPacketBlocks(view, job);
#endif
  return renderScalarBlocks(view, job);
}

// The views of this unit, by their index in ViewVariant (static: every unit has one).
static std::uint64_t renderUnitViews(std::size_t viewIndex, const void* view, const TileJob& job) {
  std::uint64_t samples = 0;
  forEachViewOfUnit<VOXWALL_VIEW_UNIT>([&](auto index) {
    using View = std::variant_alternative_t<decltype(index)::value, ViewVariant>;
    if (viewIndex == index) samples = renderViewBlocks(*static_cast<const View*>(view), job);
  });
  return samples;
}

#if VOXWALL_VIEW_UNIT == 0
std::size_t targetLanes() {
#if VOXWALL_PACKETS
  return HwyLanes::kLanes;
#else
  return 1;
#endif
}
#endif

#undef VOXWALL_PACKETS

}  // namespace HWY_NAMESPACE
}  // namespace voxwall::node::cpu
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace voxwall::node::cpu {

HWY_EXPORT(renderUnitViews);

// What cpu_backend.cpp calls (cpu_blocks.hpp): the best target's raycaster.
template <std::size_t Unit>
std::uint64_t renderUnitBlocks(std::size_t viewIndex, const void* view, const TileJob& job) {
  static_assert(Unit == VOXWALL_VIEW_UNIT);
  return HWY_DYNAMIC_DISPATCH(renderUnitViews)(viewIndex, view, job);
}
template std::uint64_t renderUnitBlocks<VOXWALL_VIEW_UNIT>(std::size_t, const void*,
                                                           const TileJob&);

}  // namespace voxwall::node::cpu

// The targets, once for the process (in unit 0's file; not in cpu_backend.cpp, because Highway's
// headers need this file's HWY_DISABLED_TARGETS).
#if VOXWALL_VIEW_UNIT == 0
namespace voxwall::node {
namespace cpu {

HWY_EXPORT(targetLanes);
std::size_t packetLanes() { return HWY_DYNAMIC_DISPATCH(targetLanes)(); }

// Highway's bits of the build's targets this CPU runs, best (lowest bit) first; never empty (the
// baseline target always runs).
static std::vector<std::int64_t> packetTargetBits() {
  std::vector<std::int64_t> out;
  for (std::int64_t t = std::int64_t(hwy::SupportedTargets()) & std::int64_t(HWY_TARGETS); t != 0;
       t &= t - 1)
    out.push_back(t & -t);
  return out;
}

std::string packetTarget() { return hwy::TargetName(packetTargetBits().front()); }

}  // namespace cpu

std::vector<std::string> cpuPacketTargets() {
  std::vector<std::string> names;
  for (const auto bit : cpu::packetTargetBits()) names.push_back(hwy::TargetName(bit));
  return names;
}

void restrictCpuPacketTarget(const std::string& name) {
  hwy::SetSupportedTargetsForTest(0);  // list every target, not those of a restriction before
  if (name.empty()) return;
  for (const auto bit : cpu::packetTargetBits())
    if (name == hwy::TargetName(bit)) return hwy::SetSupportedTargetsForTest(bit);
  throw std::invalid_argument("no SIMD target '" + name + "' in this build on this CPU");
}

}  // namespace voxwall::node
#endif  // VOXWALL_VIEW_UNIT == 0
#endif  // HWY_ONCE
