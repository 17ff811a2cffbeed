// Random access into the VQ codec's bricks (Guthe & Goesele), on the host or on a device:
// offset volume -> (index table) -> codeword, and the RBUC codeword decoder. The encoder side
// and the byte layout are documented in vq_codec.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#if !defined(__CUDA_ARCH__)
#include <memory>
#endif
#include <voxwall/codec/kernels/trilinear.hpp>

namespace voxwall::codec::kernels {

inline constexpr int kVqBrick = 4;  // voxels per brick side
inline constexpr int kVqBrickVoxels = 64;
inline constexpr int kVqEscape = 255;  // RBUC header byte: the raw voxels follow

// Reads `bits` (0..57) bits at bit offset `bit` of a little-endian bit stream. The stream must
// have 8 readable bytes past the byte that holds its last bit (the encoder pads every array).
VOXWALL_HD_INLINE std::uint64_t readBits(const std::uint8_t* p, std::uint64_t bit, int bits) {
  const std::uint8_t* q = p + (bit >> 3);
  std::uint64_t word = 0;
  for (int i = 0; i < 8; ++i) word |= std::uint64_t(q[i]) << (8 * i);
  const std::uint64_t mask = bits >= 64 ? ~std::uint64_t(0) : (std::uint64_t(1) << bits) - 1;
  return (word >> (bit & 7)) & mask;
}

VOXWALL_HD_INLINE std::uint32_t zigzagDecode(std::uint32_t z) { return (z >> 1) ^ (0u - (z & 1u)); }

// The prediction of voxel i (x fastest in the 4^3 brick) from the voxels before it, for
// transformation t: 0 none; 1 the previous voxel along the first axis (x, else y, else z) on
// which the voxel is not at the brick's low face; 2 the Lorenzo predictor over the available
// axes among x and y (a + b - c), z alone in the first column; 3 the Lorenzo predictor over every
// available axis (the "gradient" predictor). Values are relative to the brick's minimum; the
// prediction is clamped to [0, range].
VOXWALL_HD_INLINE std::int32_t vqPredict(const std::uint16_t* u, int i, int t, std::int32_t range) {
  if (t == 0) return 0;
  const int x = i & 3, y = (i >> 2) & 3, z = i >> 4;
  int axes[3];
  int n = 0;
  const int strides[3] = {1, 4, 16};
  const bool avail[3] = {x > 0, y > 0, z > 0};
  if (t == 1) {
    for (int a = 0; a < 3 && n == 0; ++a)
      if (avail[a]) axes[n++] = strides[a];
  } else if (t == 2) {
    if (avail[0]) axes[n++] = 1;
    if (avail[1]) axes[n++] = 4;
    if (n == 0 && avail[2]) axes[n++] = 16;
  } else {
    for (int a = 0; a < 3; ++a)
      if (avail[a]) axes[n++] = strides[a];
  }
  // Sum over the non-empty subsets S of the chosen axes of (-1)^(|S|+1) u[i - sum(S)].
  std::int32_t pred = 0;
  for (int s = 1; s < (1 << n); ++s) {
    int off = 0, count = 0;
    for (int a = 0; a < n; ++a)
      if (s & (1 << a)) off += axes[a], ++count;
    pred += (count & 1) ? std::int32_t(u[i - off]) : -std::int32_t(u[i - off]);
  }
  return pred < 0 ? 0 : (pred > range ? range : pred);
}

// Decodes one compressed codeword at `p` into 64 values (x fastest, the data's unsigned values).
// `bits` is the data's bit depth (8, 12 or 16). The layout is in vq_codec.hpp. The encoder
// guarantees well-formed codewords; the host validates every codeword before rendering.
VOXWALL_HD_INLINE void vqDecodeCodeword(const std::uint8_t* p, int bits, std::uint16_t* out) {
  const std::uint32_t lo = std::uint32_t(readBits(p, 0, bits));
  const std::uint32_t hi = std::uint32_t(readBits(p, std::uint64_t(bits), bits));
  p += (2 * bits + 7) / 8;
  if (lo == hi) {
    for (int i = 0; i < kVqBrickVoxels; ++i) out[i] = std::uint16_t(lo);
    return;
  }
  const int header = p[0];
  ++p;
  if (header == kVqEscape) {
    for (int i = 0; i < kVqBrickVoxels; ++i)
      out[i] = std::uint16_t(readBits(p, std::uint64_t(i) * std::uint64_t(bits), bits));
    return;
  }
  const int c2 = header & 63, t = header >> 6;
  const std::uint8_t* c0 = p + c2;  // the eight groups follow the c1 values
  const std::int32_t range = std::int32_t(hi - lo);
  for (int g = 0; g < 8; ++g) {
    const int c1 = int(readBits(p, std::uint64_t(g) * std::uint64_t(c2), c2));
    for (int j = 0; j < 8; ++j) {
      const int i = g * 8 + j;
      const std::uint32_t code =
          std::uint32_t(readBits(c0, std::uint64_t(j) * std::uint64_t(c1), c1));
      const std::int32_t pred = vqPredict(out, i, t, range);
      const std::int32_t value =
          t == 0 ? std::int32_t(code) : pred + std::int32_t(zigzagDecode(code));
      out[i] = std::uint16_t(value);
    }
    c0 += c1;
  }
  for (int i = 0; i < kVqBrickVoxels; ++i) out[i] = std::uint16_t(out[i] + lo);
}

// Decodes one plain (bit-packed) codeword.
VOXWALL_HD_INLINE void vqDecodePlain(const std::uint8_t* p, int bits, std::uint16_t* out) {
  for (int i = 0; i < kVqBrickVoxels; ++i)
    out[i] = std::uint16_t(readBits(p, std::uint64_t(i) * std::uint64_t(bits), bits));
}

// The view. `data` holds the offset volume, the index table (indirect mapping only) and the
// codebook at the byte offsets below; it points into host or device memory and is not owned.
struct VqView {
  const std::uint8_t* data = nullptr;
  std::uint64_t indexTableAt = 0, codebookAt = 0;  // byte offsets into data
  int dimX = 0, dimY = 0, dimZ = 0;
  int bricksX = 0, bricksY = 0;
  int bits = 8;         // data bit depth
  int offsetBits = 1;   // bits per offset-volume entry
  int addressBits = 0;  // bits per index-table entry (indirect mapping)
  bool compressed = false, indirect = false;
  float bias = 0;  // added to every decoded value (int16 data)
  float maxX = 0, maxY = 0, maxZ = 0;

  // Byte address in the codebook of brick (bx, by, bz)'s codeword, and a key that identifies
  // the codeword (equal keys decode to equal voxels).
  VOXWALL_HD_INLINE std::uint64_t codewordAddress(int bx, int by, int bz) const {
    const std::uint64_t brick =
        (std::uint64_t(bz) * std::uint64_t(bricksY) + std::uint64_t(by)) * std::uint64_t(bricksX) +
        std::uint64_t(bx);
    const std::uint64_t entry = readBits(data, brick * std::uint64_t(offsetBits), offsetBits);
    if (!compressed) return entry * std::uint64_t(8 * bits);  // 64 voxels of `bits` bits
    if (!indirect) return entry;
    return readBits(data + indexTableAt, entry * std::uint64_t(addressBits), addressBits);
  }

  VOXWALL_HD_INLINE void decodeAt(std::uint64_t address, std::uint16_t* out) const {
    const std::uint8_t* p = data + codebookAt + address;
    if (compressed)
      vqDecodeCodeword(p, bits, out);
    else
      vqDecodePlain(p, bits, out);
  }

  // Decoded codewords are cached. On the host, in a direct-mapped cache per thread that lives
  // across rays (neighbouring rays of a tile cross the same bricks, so most lookups hit); on a
  // device, in a few slots per ray. Entries are keyed by the view's `cacheId` (unique per
  // loaded volume) and the codeword's address.
  static constexpr int kRaySlots = 4;
  struct HostCache {
    static constexpr int kSlots = 2048;
    std::uint64_t id[kSlots];
    std::uint64_t key[kSlots];
    std::uint16_t voxels[kSlots][kVqBrickVoxels];
    std::uint64_t writes = 0;  // slots (re)filled so far: a change invalidates rays' memos
  };
  struct RayCache {
#if defined(__CUDA_ARCH__)
    std::uint64_t key[kRaySlots] = {~0ull, ~0ull, ~0ull, ~0ull};
    std::uint16_t voxels[kRaySlots][kVqBrickVoxels];
#else
    HostCache* host = nullptr;
    // The bricks this ray used last, one per parity of (bx, by, bz), so the up to 2x2x2
    // bricks around a cell or a gradient never evict each other: brick index and its voxels in
    // the host cache, valid while the cache has not refilled a slot since (memoWrites).
    std::uint64_t memoBrick[8] = {~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull, ~0ull};
    const std::uint16_t* memoVoxels[8] = {};
    std::uint64_t memoWrites = ~0ull;
#endif
    int ix = -1, iy = -1, iz = -1;  // the last voxel cell and its eight corners
    float c[8] = {};
  };
  std::uint64_t cacheId = 0;

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

  // Decoded codeword of the brick at (bx, by, bz), through the cache.
  VOXWALL_HD_INLINE const std::uint16_t* brick(int bx, int by, int bz, RayCache& cache) const {
#if defined(__CUDA_ARCH__)
    const std::uint64_t address = codewordAddress(bx, by, bz);
    const int slot = int(((address + 1) * 0x9E3779B97F4A7C15ull) >> 62);
    if (cache.key[slot] != address) {
      decodeAt(address, cache.voxels[slot]);
      cache.key[slot] = address;
    }
    return cache.voxels[slot];
#else
    if (!cache.host) cache.host = &hostCache();
    HostCache& h = *cache.host;
    const std::uint64_t brick =
        (std::uint64_t(bz) * std::uint64_t(bricksY) + std::uint64_t(by)) * std::uint64_t(bricksX) +
        std::uint64_t(bx);
    const int m = (bx & 1) | ((by & 1) << 1) | ((bz & 1) << 2);
    if (cache.memoWrites == h.writes && cache.memoBrick[m] == brick) return cache.memoVoxels[m];
    const std::uint64_t address = codewordAddress(bx, by, bz);
    const int slot = int(((address ^ (cacheId << 40)) * 0x9E3779B97F4A7C15ull) >> 53);
    if (h.key[slot] != address || h.id[slot] != cacheId) {
      decodeAt(address, h.voxels[slot]);
      h.key[slot] = address, h.id[slot] = cacheId;
      ++h.writes;
    }
    if (cache.memoWrites != h.writes) {  // a slot was refilled: forget every memo
      for (int i = 0; i < 8; ++i) cache.memoBrick[i] = ~0ull;
      cache.memoWrites = h.writes;
    }
    cache.memoBrick[m] = brick, cache.memoVoxels[m] = h.voxels[slot];
    return h.voxels[slot];
#endif
  }

  // Voxel (x, y, z), clamped to the volume.
  VOXWALL_HD_INLINE float voxel(int x, int y, int z, RayCache& cache) const {
    x = clampIndex(x, dimX), y = clampIndex(y, dimY), z = clampIndex(z, dimZ);
    const std::uint16_t* b = brick(x >> 2, y >> 2, z >> 2, cache);
    return float(b[(x & 3) + ((y & 3) << 2) + ((z & 3) << 4)]) + bias;
  }
  VOXWALL_HD_INLINE float voxel(int x, int y, int z) const {
    RayCache cache;
    return voxel(x, y, z, cache);
  }

  VOXWALL_HD_INLINE float sample(float x, float y, float z) const {
    RayCache cache;
    return sample(x, y, z, cache);
  }

  // The eight corners of voxel cell (ix, iy, iz) (clamped at the far faces), from the up to
  // 2x2x2 bricks the cell touches: each brick is looked up once, and its corners are read
  // before the next lookup (which may reuse its cache slot).
  VOXWALL_HD_INLINE void corners(int ix, int iy, int iz, RayCache& cache, float* c) const {
    const int x1 = ix + 1 < dimX ? ix + 1 : ix, y1 = iy + 1 < dimY ? iy + 1 : iy;
    const int z1 = iz + 1 < dimZ ? iz + 1 : iz;
    const int bx[2] = {ix >> 2, x1 >> 2}, by[2] = {iy >> 2, y1 >> 2}, bz[2] = {iz >> 2, z1 >> 2};
    // Bit a of `split` is set when the cell crosses a brick border along axis a; corner i
    // (bit 0: x + 1, bit 1: y + 1, bit 2: z + 1) lies in the brick of corner (i & split).
    const int split = int(bx[1] != bx[0]) | (int(by[1] != by[0]) << 1) | (int(bz[1] != bz[0]) << 2);
    if (split == 0) {  // the common case: the whole cell in one brick
      const std::uint16_t* b = brick(bx[0], by[0], bz[0], cache);
      const int i0 = (ix & 3) + ((iy & 3) << 2) + ((iz & 3) << 4);
      const int dx = x1 - ix, dy = (y1 - iy) << 2, dz = (z1 - iz) << 4;
      c[0] = float(b[i0]) + bias, c[1] = float(b[i0 + dx]) + bias;
      c[2] = float(b[i0 + dy]) + bias, c[3] = float(b[i0 + dy + dx]) + bias;
      c[4] = float(b[i0 + dz]) + bias, c[5] = float(b[i0 + dz + dx]) + bias;
      c[6] = float(b[i0 + dz + dy]) + bias, c[7] = float(b[i0 + dz + dy + dx]) + bias;
      return;
    }
    const int lx[2] = {ix & 3, x1 & 3}, ly[2] = {(iy & 3) << 2, (y1 & 3) << 2};
    const int lz[2] = {(iz & 3) << 4, (z1 & 3) << 4};
    for (int j = 0; j < 8; ++j) {
      if ((j & split) != j) continue;
      const std::uint16_t* b = brick(bx[j & 1], by[(j >> 1) & 1], bz[j >> 2], cache);
      for (int i = j; i < 8; ++i)
        if ((i & split) == j) c[i] = float(b[lx[i & 1] + ly[(i >> 1) & 1] + lz[i >> 2]]) + bias;
    }
  }

  VOXWALL_HD_INLINE static float lerp3(const float* c, float tx, float ty, float tz) {
    const float c00 = c[0] + tx * (c[1] - c[0]), c10 = c[2] + tx * (c[3] - c[2]);
    const float c01 = c[4] + tx * (c[5] - c[4]), c11 = c[6] + tx * (c[7] - c[6]);
    const float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    return c0 + tz * (c1 - c0);
  }

  // A gradient neighbour: shares the decoded bricks of the ray's cache but leaves its last
  // cell (the main sample's) alone.
  VOXWALL_HD_INLINE float sampleNear(float x, float y, float z, RayCache& cache) const {
    x = x < 0.0f ? 0.0f : (x > maxX ? maxX : x);
    y = y < 0.0f ? 0.0f : (y > maxY ? maxY : y);
    z = z < 0.0f ? 0.0f : (z > maxZ ? maxZ : z);
    const int ix = int(x), iy = int(y), iz = int(z);
    float c[8];
    corners(ix, iy, iz, cache, c);
    return lerp3(c, x - float(ix), y - float(iy), z - float(iz));
  }

  // Trilinear sample with clamp-to-edge, like RawView::sample.
  VOXWALL_HD_INLINE float sample(float x, float y, float z, RayCache& cache) const {
    x = x < 0.0f ? 0.0f : (x > maxX ? maxX : x);
    y = y < 0.0f ? 0.0f : (y > maxY ? maxY : y);
    z = z < 0.0f ? 0.0f : (z > maxZ ? maxZ : z);
    const int ix = int(x), iy = int(y), iz = int(z);
    if (ix != cache.ix || iy != cache.iy || iz != cache.iz) {
      corners(ix, iy, iz, cache, cache.c);
      cache.ix = ix, cache.iy = iy, cache.iz = iz;
    }
    return lerp3(cache.c, x - float(ix), y - float(iy), z - float(iz));
  }
};

static_assert(std::is_trivially_copyable_v<VqView>);

}  // namespace voxwall::codec::kernels
