// A view for any codec that stores the volume as bricks of M^3 voxels and decodes a whole brick
// at a time (vq, ksvd, tvq, zfp). The codec supplies a Decoder ("which
// stored brick is at (bx, by, bz)" and "decode it into M^3 values"); this view supplies the rest:
// the decoded-brick caches, the per-parity memo, the cell corners across brick borders, the
// position clamp and the trilinear blend. Host-side helpers over the same decoder (value ranges,
// full decode) are in brick_volume.hpp.
#pragma once

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#if !defined(__CUDA_ARCH__)
#include <memory>
#endif
#include <voxwall/codec/kernels/trilinear.hpp>

namespace voxwall::codec::kernels {

// What a codec gives CachedBrickView:
//   kBrickSide        M, the brick side in voxels (2..16; a power of two divides by shifts)
//   Value             the type of a decoded voxel (kept in the caches; uint16_t, float, ...)
//   key(bx, by, bz)   a key of brick (bx, by, bz)'s stored form: equal keys decode to equal
//                     voxels (a codeword address, a block index); never ~0
//   decode(key, out)  writes the brick's M^3 values, x fastest
//   scalar(value)     a decoded value as the float the raycaster samples (bias, scale)
// A decoder is a small trivially copyable value, like the view that holds it.
template <class D>
concept BrickDecoder = std::is_trivially_copyable_v<D> &&
                       (D::kBrickSide >= 2 && D::kBrickSide <= 16) &&
                       requires(const D& d, int b, std::uint64_t key, typename D::Value* out,
                                typename D::Value v) {
  { d.key(b, b, b) } -> std::same_as<std::uint64_t>;
  d.decode(key, out);
  { d.scalar(v) } -> std::same_as<float>;
};

// Slots of the per-thread host cache: about 256 KiB of decoded voxels (2048 bricks of 4^3
// 16-bit voxels), a power of two.
constexpr int cachedBrickSlotLog2(std::size_t brickBytes) {
  int log2 = 4;
  while (log2 < 16 && (std::size_t(2) << log2) * brickBytes <= (std::size_t(256) << 10)) ++log2;
  return log2;
}

template <BrickDecoder Decoder>
struct CachedBrickView {
  using DecoderType = Decoder;
  using Value = typename Decoder::Value;
  static constexpr int kSide = Decoder::kBrickSide;
  static constexpr int kVoxels = kSide * kSide * kSide;
  // Brick of a non-negative voxel index, and the index within it (shifts when kSide is a power
  // of two: the division is by a constant).
  static VOXWALL_HD_INLINE int brickOf(int i) { return int(unsigned(i) / unsigned(kSide)); }
  static VOXWALL_HD_INLINE int within(int i) { return int(unsigned(i) % unsigned(kSide)); }

  Decoder decoder;
  int dimX = 0, dimY = 0, dimZ = 0;
  int bricksX = 0, bricksY = 0;
  float maxX = 0, maxY = 0, maxZ = 0;  // dim - 1, for clamping positions
  // Unique per loaded volume: keys the per-thread host cache, which outlives views.
  std::uint64_t cacheId = 0;

  // Sets the geometry from the volume's size (the decoder is set by the caller).
  VOXWALL_HD_INLINE void setDims(int x, int y, int z) {
    dimX = x, dimY = y, dimZ = z;
    bricksX = (x + kSide - 1) / kSide, bricksY = (y + kSide - 1) / kSide;
    maxX = float(x - 1), maxY = float(y - 1), maxZ = float(z - 1);
  }

  // Decoded bricks are cached. On the host, in a direct-mapped cache per thread that lives
  // across rays (neighbouring rays of a tile cross the same bricks, so most lookups hit); on a
  // device, in a few slots per ray. Host entries are keyed by cacheId and the brick's key.
  static constexpr int kRaySlots = 4;
  struct HostCache {
    static constexpr int kSlotLog2 = cachedBrickSlotLog2(sizeof(Value) * kVoxels);
    static constexpr int kSlots = 1 << kSlotLog2;
    std::uint64_t id[kSlots];
    std::uint64_t key[kSlots];
    Value voxels[kSlots][kVoxels];
    std::uint64_t writes = 0;  // slots (re)filled so far: a change invalidates rays' memos
  };
  struct RayCache {
#if defined(__CUDA_ARCH__)
    std::uint64_t key[kRaySlots] = {~0ull, ~0ull, ~0ull, ~0ull};
    Value voxels[kRaySlots][kVoxels];
#else
    HostCache* host = nullptr;
    // The bricks this ray used last, one per parity of (bx, by, bz), so the up to 2x2x2
    // bricks around a cell or a gradient never evict each other: brick index and its voxels in
    // the host cache, valid while the cache has not refilled a slot since (memoWrites).
    std::uint64_t memoBrick[8] = {~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull};
    const Value* memoVoxels[8] = {};
    std::uint64_t memoWrites = ~0ull;
#endif
    int ix = -1, iy = -1, iz = -1;  // the last voxel cell and its eight corners
    float c[8] = {};
    CellGradient grad;  // the corner differences of the last shaded cell
  };

#if !defined(__CUDA_ARCH__)
  static HostCache& hostCache() {
    thread_local const std::unique_ptr<HostCache> cache = [] {
      auto c = std::make_unique<HostCache>();
      for (int i = 0; i < HostCache::kSlots; ++i) c->id[i] = 0, c->key[i] = ~0ull;
      return c;
    }();
    return *cache;
  }
#endif

  // The decoded voxels of brick (bx, by, bz), through the cache.
  VOXWALL_HD_INLINE const Value* brick(int bx, int by, int bz, RayCache& cache) const {
#if defined(__CUDA_ARCH__)
    const std::uint64_t key = decoder.key(bx, by, bz);
    const int slot = int(((key + 1) * 0x9E3779B97F4A7C15ull) >> 62);
    if (cache.key[slot] != key) {
      decoder.decode(key, cache.voxels[slot]);
      cache.key[slot] = key;
    }
    return cache.voxels[slot];
#else
    if (!cache.host) cache.host = &hostCache();
    HostCache& h = *cache.host;
    const std::uint64_t index =
        (std::uint64_t(bz) * std::uint64_t(bricksY) + std::uint64_t(by)) * std::uint64_t(bricksX) +
        std::uint64_t(bx);
    const int m = (bx & 1) | ((by & 1) << 1) | ((bz & 1) << 2);
    if (cache.memoWrites == h.writes && cache.memoBrick[m] == index) return cache.memoVoxels[m];
    const std::uint64_t key = decoder.key(bx, by, bz);
    const int slot =
        int(((key ^ (cacheId << 40)) * 0x9E3779B97F4A7C15ull) >> (64 - HostCache::kSlotLog2));
    if (h.key[slot] != key || h.id[slot] != cacheId) {
      decoder.decode(key, h.voxels[slot]);
      h.key[slot] = key, h.id[slot] = cacheId;
      ++h.writes;
    }
    if (cache.memoWrites != h.writes) {  // a slot was refilled: forget every memo
      for (int i = 0; i < 8; ++i) cache.memoBrick[i] = ~0ull;
      cache.memoWrites = h.writes;
    }
    cache.memoBrick[m] = index, cache.memoVoxels[m] = h.voxels[slot];
    return h.voxels[slot];
#endif
  }

  // Voxel (x, y, z), clamped to the volume.
  VOXWALL_HD_INLINE float voxel(int x, int y, int z, RayCache& cache) const {
    x = clampIndex(x, dimX), y = clampIndex(y, dimY), z = clampIndex(z, dimZ);
    const Value* b = brick(brickOf(x), brickOf(y), brickOf(z), cache);
    return decoder.scalar(b[within(x) + kSide * (within(y) + kSide * within(z))]);
  }
  VOXWALL_HD_INLINE float voxel(int x, int y, int z) const {
    RayCache cache;
    return voxel(x, y, z, cache);
  }

  // The eight corners of voxel cell (ix, iy, iz) (clamped at the far faces), from the up to
  // 2x2x2 bricks the cell touches: each brick is looked up once, and its corners are read
  // before the next lookup (which may reuse its cache slot).
  VOXWALL_HD_INLINE void corners(int ix, int iy, int iz, RayCache& cache, float* c) const {
    const int x1 = ix + 1 < dimX ? ix + 1 : ix, y1 = iy + 1 < dimY ? iy + 1 : iy;
    const int z1 = iz + 1 < dimZ ? iz + 1 : iz;
    const int bx[2] = {brickOf(ix), brickOf(x1)}, by[2] = {brickOf(iy), brickOf(y1)};
    const int bz[2] = {brickOf(iz), brickOf(z1)};
    // Bit a of `split` is set when the cell crosses a brick border along axis a; corner i
    // (bit 0: x + 1, bit 1: y + 1, bit 2: z + 1) lies in the brick of corner (i & split).
    const int split = int(bx[1] != bx[0]) | (int(by[1] != by[0]) << 1) | (int(bz[1] != bz[0]) << 2);
    if (split == 0) {  // the common case: the whole cell in one brick
      const Value* b = brick(bx[0], by[0], bz[0], cache);
      const int i0 = within(ix) + kSide * (within(iy) + kSide * within(iz));
      const int dx = x1 - ix, dy = (y1 - iy) * kSide, dz = (z1 - iz) * kSide * kSide;
      c[0] = decoder.scalar(b[i0]), c[1] = decoder.scalar(b[i0 + dx]);
      c[2] = decoder.scalar(b[i0 + dy]), c[3] = decoder.scalar(b[i0 + dy + dx]);
      c[4] = decoder.scalar(b[i0 + dz]), c[5] = decoder.scalar(b[i0 + dz + dx]);
      c[6] = decoder.scalar(b[i0 + dz + dy]), c[7] = decoder.scalar(b[i0 + dz + dy + dx]);
      return;
    }
    const int lx[2] = {within(ix), within(x1)};
    const int ly[2] = {within(iy) * kSide, within(y1) * kSide};
    const int lz[2] = {within(iz) * kSide * kSide, within(z1) * kSide * kSide};
    for (int j = 0; j < 8; ++j) {
      if ((j & split) != j) continue;
      const Value* b = brick(bx[j & 1], by[(j >> 1) & 1], bz[j >> 2], cache);
      for (int i = j; i < 8; ++i)
        if ((i & split) == j) c[i] = decoder.scalar(b[lx[i & 1] + ly[(i >> 1) & 1] + lz[i >> 2]]);
    }
  }

  // A gradient neighbour: shares the decoded bricks of the ray's cache but leaves its last
  // cell (the main sample's) alone.
  VOXWALL_HD_INLINE float sampleNear(float x, float y, float z, RayCache& cache) const {
    x = clampPosition(x, maxX), y = clampPosition(y, maxY), z = clampPosition(z, maxZ);
    const int ix = int(x), iy = int(y), iz = int(z);
    float c[8];
    corners(ix, iy, iz, cache, c);
    return blendCorners(c, x - float(ix), y - float(iy), z - float(iz));
  }

  // Trilinear sample with clamp-to-edge, like RawView::sample.
  VOXWALL_HD_INLINE float sample(float x, float y, float z, RayCache& cache) const {
    x = clampPosition(x, maxX), y = clampPosition(y, maxY), z = clampPosition(z, maxZ);
    const int ix = int(x), iy = int(y), iz = int(z);
    if (ix != cache.ix || iy != cache.iy || iz != cache.iz) {
      corners(ix, iy, iz, cache, cache.c);
      cache.ix = ix, cache.iy = iy, cache.iz = iz;
    }
    return blendCorners(cache.c, x - float(ix), y - float(iy), z - float(iz));
  }
  VOXWALL_HD_INLINE float sample(float x, float y, float z) const {
    RayCache cache;
    return sample(x, y, z, cache);
  }

  // The 24 voxels around a cell that cornerDifferences reads, through the ray's brick memo: the
  // brick and the index within it of offsets -1 .. 2 along each axis (clamped) are worked out
  // once, so a read is a memo lookup and a load.
  struct Around {
    const CachedBrickView* view;
    RayCache* cache;
    int b[3][4], w[3][4];
    VOXWALL_HD_INLINE Around(const CachedBrickView* v, RayCache* c, int ix, int iy, int iz)
        : view(v), cache(c) {
      const int i[3] = {ix, iy, iz}, n[3] = {v->dimX, v->dimY, v->dimZ};
      for (int a = 0; a < 3; ++a)
        for (int o = 0; o < 4; ++o) {
          const int q = clampIndex(i[a] + o - 1, n[a]);
          b[a][o] = brickOf(q), w[a][o] = within(q);
        }
    }
    VOXWALL_HD_INLINE float operator()(int ox, int oy, int oz) const {
      const Value* p = view->brick(b[0][ox + 1], b[1][oy + 1], b[2][oz + 1], *cache);
      return view->decoder.scalar(p[w[0][ox + 1] + kSide * (w[1][oy + 1] + kSide * w[2][oz + 1])]);
    }
  };

  // The gradient hook (GradientView): after sample(x, y, z, cache) at the same position.
  VOXWALL_HD_INLINE bool gradient(float x, float y, float z, RayCache& cache, float* g) const {
    if (outsideGrid(x, y, z, maxX, maxY, maxZ)) return false;
    const int ix = int(x), iy = int(y), iz = int(z);
    if (!cache.grad.holds(ix, iy, iz)) {
      cornerDifferences(cache.c, Around(this, &cache, ix, iy, iz), cache.grad.d);
      cache.grad.ix = ix, cache.grad.iy = iy, cache.grad.iz = iz;
    }
    cache.grad.blend(x - float(ix), y - float(iy), z - float(iz), g);
    return true;
  }
};

// A CachedBrickView of some decoder (what the host-side helpers in brick_volume.hpp take).
template <class V>
concept BrickView = requires {
  typename V::DecoderType;
}
&&std::same_as<V, CachedBrickView<typename V::DecoderType>>;

}  // namespace voxwall::codec::kernels
