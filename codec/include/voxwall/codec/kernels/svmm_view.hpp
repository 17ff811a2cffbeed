// Random access into a Sparse Voxel Mip-Map (Faas 2016) on the host or on a device: refinement
// from the root through the sub-block offsets (thesis section 3.1), a per-ray cache of the last
// block visited on every level (so a ray re-refines from the deepest block that still contains
// the next voxel instead of from the root, section 3.2.2), trilinear or nearest-voxel samples,
// the constant region a sample lies in (for skipping a terminal block in one step, section
// 3.2.3) and level-of-detail sampling from the coarser levels (section 3.2.4). The byte layout
// and the encoder are documented in svmm_codec.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <voxwall/codec/kernels/trilinear.hpp>
#if defined(__CUDACC__)
#include <cuda_runtime.h>
#endif

namespace voxwall::codec::kernels {

inline constexpr int kSvmmMaxLevels = 16;

// Voxel formats (stored in files).
enum SvmmFormat : int { kSvmmDensity8 = 1, kSvmmDensity16 = 2, kSvmmRgba32 = 3 };

// Non-base voxel word: the value in the high bits, bit 4 = terminal, bits 3..0 = one nibble of
// the sub-block's 32-bit child offset (nibble j belongs to the sub-block's voxel j).
inline constexpr std::uint32_t kSvmmTerminal = 16;

// 3-bit alpha of an RGBA32 non-base word, expanded to 8 bits (round(a3 * 255 / 7)).
VOXWALL_HD_INLINE std::uint32_t svmmExpandAlpha3(std::uint32_t a3) { return (a3 * 255u + 3u) / 7u; }

// Bytes of a base voxel and of a non-base word of a format.
VOXWALL_HD_INLINE int svmmBaseBytes(int format) {
  return format == kSvmmDensity8 ? 1 : (format == kSvmmDensity16 ? 2 : 4);
}
VOXWALL_HD_INLINE int svmmWordBytes(int format) { return format == kSvmmDensity8 ? 2 : 4; }

// RGBA values are packed r | g << 8 | b << 16 | a << 24.
VOXWALL_HD_INLINE std::uint32_t svmmWordValue(int format, std::uint32_t w) {
  if (format == kSvmmDensity8) return w >> 8;
  if (format == kSvmmDensity16) return w >> 16;
  return (w >> 24) | (((w >> 16) & 255u) << 8) | (((w >> 8) & 255u) << 16) |
         (svmmExpandAlpha3((w >> 5) & 7u) << 24);
}

struct SvmmLevel {
  const std::uint8_t* data = nullptr;  // first block of the level
  std::uint64_t blockBytes = 0;        // bytes per block (the root: the whole root grid)
  int shift = 0;                       // log2 of the mipmap factor: one voxel = 2^shift voxels
  int widthLog2 = 0;                   // log2 of the block width (root: unused)
  // Block pool (section 3.3; not for the root or a block-compressed base): when `pool` is set,
  // the level's blocks are read from a 3D array of 2^poolULog2 x 2^poolVLog2 x W blocks, x
  // fastest, block b at svmmPoolBlock(b) (the layout of a CUDA 3D texture), instead of `data`.
  // On a device, `texture` (a cudaTextureObject_t over that array, 0: none) is read instead, and
  // `pool` may then be null.
  const std::uint8_t* pool = nullptr;
  int poolULog2 = 0, poolVLog2 = 0;
  unsigned long long texture = 0;
};

// Block pool extents for n blocks (section 3.3): U = V = the power of two at or below the cube
// root of n, W = ceil(n / (U V)).
struct SvmmPoolShape {
  int uLog2 = 0, vLog2 = 0;
  std::uint64_t w = 0;
};
VOXWALL_HD_INLINE SvmmPoolShape svmmPoolShape(std::uint64_t blocks) {
  SvmmPoolShape s;
  if (!blocks) return s;
  int k = 0;  // largest k with 2^(3k) <= blocks
  while (k < 20 && (std::uint64_t(1) << (3 * (k + 1))) <= blocks) ++k;
  s.uLog2 = s.vLog2 = k;
  const std::uint64_t uv = std::uint64_t(1) << (2 * k);
  s.w = (blocks + uv - 1) / uv;
  return s;
}
// Block b's position in the pool, in blocks: u = b mod U, v = (b / U) mod V, w = b / (U V).
// (The thesis prints u = o - (v + w), v = (o - w) / V, which leaves the pool for U = V = 2, o = 3;
// this is the decomposition its shifts describe.)
VOXWALL_HD_INLINE void svmmPoolBlock(std::uint64_t b, int uLog2, int vLog2, std::uint64_t& u,
                                     std::uint64_t& v, std::uint64_t& w) {
  u = b & ((std::uint64_t(1) << uLog2) - 1);
  v = (b >> uLog2) & ((std::uint64_t(1) << vLog2) - 1);
  w = b >> (uLog2 + vLog2);
}

struct SvmmLevelPages;

struct SvmmView {
  SvmmLevel level[kSvmmMaxLevels];
  int levels = 1;
  int format = kSvmmDensity8;
  bool blockCompressed = false;  // base blocks stored as 2^3 groups: bitmap + one value
  int bias = 0;                  // stored = value + bias (int16 data)
  int dimX = 1, dimY = 1, dimZ = 1;
  int rootX = 1, rootY = 1, rootZ = 1;  // the root grid (padded to even when levels > 1)
  float maxX = 0, maxY = 0, maxZ = 0;   // dim - 1, for clamping positions
  // Unique per loaded volume (keys the CPU backend's decoded pages).
  std::uint64_t cacheId = 0;

  VOXWALL_HD_INLINE int baseBytes() const { return svmmBaseBytes(format); }
  VOXWALL_HD_INLINE std::uint32_t load(const std::uint8_t* p, int bytes) const {
    std::uint32_t v = p[0];
    if (bytes > 1) v |= std::uint32_t(p[1]) << 8;
    if (bytes > 2) v |= std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
    return v;
  }
  // An element at an address aligned to its size (every level starts at a multiple of 8 and
  // holds elements of one size; only block-compressed groups are unaligned, and use load()).
  VOXWALL_HD_INLINE std::uint32_t loadAligned(const std::uint8_t* p, int bytes) const {
    if (bytes == 1) return *p;
    if (bytes == 2) return *reinterpret_cast<const std::uint16_t*>(p);
    return *reinterpret_cast<const std::uint32_t*>(p);
  }
  // Non-base word `index` of a block (16-bit for DENSITY8, else 32-bit; levels are aligned).
  VOXWALL_HD_INLINE std::uint32_t word(const std::uint8_t* block, std::size_t index) const {
    if (format == kSvmmDensity8) return reinterpret_cast<const std::uint16_t*>(block)[index];
    return reinterpret_cast<const std::uint32_t*>(block)[index];
  }
  // Base voxel (lx, ly, lz) of a base block (or of the root grid when there is one level).
  VOXWALL_HD_INLINE std::uint32_t baseValue(const std::uint8_t* block, int lx, int ly,
                                            int lz) const {
    const int bytes = baseBytes();
    if (levels == 1) {
      const std::size_t i =
          (std::size_t(lz) * std::size_t(rootY) + std::size_t(ly)) * std::size_t(rootX) +
          std::size_t(lx);
      return load(block + i * std::size_t(bytes), bytes);
    }
    const int wl = level[0].widthLog2;
    if (!blockCompressed)
      return load(block + (std::size_t(lx | (ly << wl) | (lz << (2 * wl))) * std::size_t(bytes)),
                  bytes);
    const int gl = wl - 1;  // groups per side: w / 2
    const std::size_t group = std::size_t((lx >> 1) | ((ly >> 1) << gl) | ((lz >> 1) << (2 * gl)));
    const std::uint8_t* g = block + group * std::size_t(1 + bytes);
    const int bit = (lx & 1) | ((ly & 1) << 1) | ((lz & 1) << 2);
    return (g[0] >> bit) & 1 ? load(g + 1, bytes) : 0u;
  }
  // A block handle: the block's address for a linear level, its index for a pooled one.
  VOXWALL_HD_INLINE std::uint64_t handle(int L, std::uint64_t b) const {
    const SvmmLevel& l = level[L];
    return l.pool || l.texture
               ? b
               : std::uint64_t(reinterpret_cast<std::uintptr_t>(l.data + b * l.blockBytes));
  }
  // Element (lx, ly, lz) of `bytes` bytes of the block with handle h of level L: the root grid
  // (h unused), a linear block, or a pooled one (texture on a device when there is one).
  VOXWALL_HD_INLINE std::uint32_t element(int L, std::uint64_t h, int lx, int ly, int lz,
                                          int bytes) const {
    const SvmmLevel& l = level[L];
    if (L == levels - 1) {
      const std::size_t i =
          (std::size_t(lz) * std::size_t(rootY) + std::size_t(ly)) * std::size_t(rootX) +
          std::size_t(lx);
      return loadAligned(l.data + i * std::size_t(bytes), bytes);
    }
    const int wl = l.widthLog2;
    if (!l.pool && !l.texture)
      return loadAligned(reinterpret_cast<const std::uint8_t*>(std::uintptr_t(h)) +
                             std::size_t(lx | (ly << wl) | (lz << (2 * wl))) * std::size_t(bytes),
                         bytes);
    return pooled(l, h, lx, ly, lz, bytes);
  }

  // A pooled element (out of line on the host, where pools are only used by tests).
#if defined(__CUDACC__) || !defined(__GNUC__)
  VOXWALL_HD
#else
  __attribute__((noinline))
#endif
  std::uint32_t pooled(const SvmmLevel& l, std::uint64_t b, int lx, int ly, int lz,
                       int bytes) const {
    const int wl = l.widthLog2;
    std::uint64_t u, v, w;
    svmmPoolBlock(b, l.poolULog2, l.poolVLog2, u, v, w);
    const std::uint64_t x = (u << wl) + std::uint64_t(lx), y = (v << wl) + std::uint64_t(ly),
                        z = (w << wl) + std::uint64_t(lz);
#if defined(__CUDA_ARCH__)
    if (l.texture) {
      const float fx = float(x) + 0.5f, fy = float(y) + 0.5f, fz = float(z) + 0.5f;
      if (bytes == 1) return tex3D<unsigned char>(l.texture, fx, fy, fz);
      if (bytes == 2) return tex3D<unsigned short>(l.texture, fx, fy, fz);
      return tex3D<unsigned int>(l.texture, fx, fy, fz);
    }
#endif
    const std::uint64_t i = (((z << (l.poolVLog2 + wl)) + y) << (l.poolULog2 + wl)) + x;
    return loadAligned(l.pool + i * std::uint64_t(bytes), bytes);
  }
  VOXWALL_HD_INLINE int wordBytes() const { return svmmWordBytes(format); }
  // Base voxel (lx, ly, lz) of the base block with handle h (the root grid when there is one
  // level).
  VOXWALL_HD_INLINE std::uint32_t base(std::uint64_t h, int lx, int ly, int lz) const {
    if (!blockCompressed) return element(0, h, lx, ly, lz, baseBytes());
    return baseValue(reinterpret_cast<const std::uint8_t*>(std::uintptr_t(h)), lx, ly, lz);
  }

  // The stored value as a scalar (RGBA: its alpha).
  VOXWALL_HD_INLINE float scalar(std::uint32_t v) const {
    return format == kSvmmRgba32 ? float(v >> 24) : float(int(v) - bias);
  }

  // Per-ray state: the last block visited on every level, the last trilinear cell, the constant
  // region of the last sample, and what the raycaster sets before each sample.
  struct RayCache {
    int kx[kSvmmMaxLevels], ky[kSvmmMaxLevels], kz[kSvmmMaxLevels];
    std::uint64_t block[kSvmmMaxLevels];  // block handles; level 0 unused: see below
    // Base blocks, one per parity of the block coordinates: a trilinear cell straddling block
    // borders touches up to eight neighbouring blocks, which all fit.
    int bx0[8], by0[8], bz0[8];
    std::uint64_t block0[8];
    int ix = -1, iy = -1, iz = -1, il = -1;  // cell (lower corner) and level of c[]
    float c[8] = {};
    int cellStop = 0, cellVx = 0, cellVy = 0, cellVz = 0;  // see sample()
    bool cellConstant = false;
    CellGradient grad;  // the corner differences of the last shaded full-resolution cell
    // Index-space box [regionLo, regionHi) around the last sample in which every sample has the
    // same value, valid while the footprint stays below regionFootprintMax.
    bool regionValid = false;
    float regionLo[3] = {}, regionHi[3] = {};
    float regionFootprintMax = 0.0f;
    // Set by the raycaster: the ray's footprint at this sample in voxels (0: finest level only)
    // and nearest-voxel sampling instead of trilinear.
    float footprint = 0.0f;
    bool nearest = false;
    VOXWALL_HD_INLINE RayCache() {
      for (int i = 0; i < kSvmmMaxLevels; ++i) kx[i] = -1, ky[i] = -1, kz[i] = -1, block[i] = 0;
      for (int i = 0; i < 8; ++i) bx0[i] = -1, by0[i] = -1, bz0[i] = -1, block0[i] = 0;
    }
  };
  // Tells the raycaster that this view reports constant regions and takes footprints.
  static constexpr bool kTraversal = true;

  // Level-`target` voxel (gx, gy, gz) (inside the level's grid): refines from the deepest cached
  // block containing it (the root when none) until a terminal voxel or the target level. Returns
  // the stored value; `stop` is the level it came from (> target: a terminal voxel there).
  VOXWALL_HD_INLINE std::uint32_t lookup(int gx, int gy, int gz, int target, RayCache& c,
                                         int& stop) const {
    const int top = levels - 1;
    int L = target;
    if (target == 0 && top > 0) {
      const int wl = level[0].widthLog2;
      const int bx = gx >> wl, by = gy >> wl, bz = gz >> wl;
      const int slot = (bx & 1) | ((by & 1) << 1) | ((bz & 1) << 2);
      if (c.bx0[slot] == bx && c.by0[slot] == by && c.bz0[slot] == bz) {
        stop = 0;
        const int m = (1 << wl) - 1;
        return base(c.block0[slot], gx & m, gy & m, gz & m);
      }
      L = 1;
    }
    return refine(gx, gy, gz, target, L, c, stop);
  }

  // The rest of lookup(): out of line on the host, so the cached path stays small where it is
  // inlined (eight times per cell).
#if defined(__CUDACC__) || !defined(__GNUC__)
  VOXWALL_HD
#else
  __attribute__((noinline))
#endif
  std::uint32_t refine(int gx, int gy, int gz, int target, int L, RayCache& c, int& stop) const {
    const int top = levels - 1;
    const int ts = level[target].shift;
    std::uint64_t block = 0;
    bool cached = false;
    for (; L < top; ++L) {
      const int sh = level[L].shift - ts + level[L].widthLog2;
      if (c.kx[L] == (gx >> sh) && c.ky[L] == (gy >> sh) && c.kz[L] == (gz >> sh)) {
        block = c.block[L];
        cached = true;
        break;
      }
    }
    if (!cached) L = top, block = 0;
    const int wb = wordBytes();
    for (;;) {
      const int sh = level[L].shift - ts;
      int lx = gx >> sh, ly = gy >> sh, lz = gz >> sh;
      if (L == 0) {
        stop = 0;
        const int m = levels == 1 ? 0x7fffffff : (1 << level[0].widthLog2) - 1;
        return base(block, lx & m, ly & m, lz & m);
      }
      if (L != top) {
        const int m = (1 << level[L].widthLog2) - 1;
        lx &= m, ly &= m, lz &= m;
      }
      const int k = (lx & 1) | ((ly & 1) << 1) | ((lz & 1) << 2);
      std::uint32_t w, words[8] = {};
      if (L == top || (!level[L].pool && !level[L].texture)) {
        // Linear: the word and its sub-block by strides from the block's address.
        const std::uint8_t* p = L == top
                                    ? level[top].data
                                    : reinterpret_cast<const std::uint8_t*>(std::uintptr_t(block));
        std::size_t sy, sz;
        if (L == top) {
          sy = std::size_t(rootX), sz = std::size_t(rootX) * std::size_t(rootY);
        } else {
          sy = std::size_t(1) << level[L].widthLog2, sz = sy << level[L].widthLog2;
        }
        w = word(p, std::size_t(lz) * sz + std::size_t(ly) * sy + std::size_t(lx));
        if (!(w & kSvmmTerminal) && L != target) {
          const std::size_t s0 =
              std::size_t(lz & ~1) * sz + std::size_t(ly & ~1) * sy + std::size_t(lx & ~1);
          for (int j = 0; j < 8; ++j)
            words[j] = word(p, s0 + std::size_t(j & 1) + (j & 2 ? sy : 0) + (j & 4 ? sz : 0));
        }
      } else {
        w = element(L, block, lx, ly, lz, wb);
        if (!(w & kSvmmTerminal) && L != target)
          for (int j = 0; j < 8; ++j)
            words[j] = element(L, block, (lx & ~1) + (j & 1), (ly & ~1) + ((j >> 1) & 1),
                               (lz & ~1) + (j >> 2), wb);
      }
      if ((w & kSvmmTerminal) || L == target) {
        stop = L;
        return svmmWordValue(format, w);
      }
      // The sub-block: one offset in its eight nibbles, then count the non-terminal voxels
      // before this one (section 2.2.2).
      std::uint32_t offset = 0, before = 0;
      for (int j = 0; j < 8; ++j) {
        offset |= (words[j] & 15u) << (4 * j);
        before += std::uint32_t(j < k && !(words[j] & kSvmmTerminal));
      }
      --L;
      block = handle(L, std::uint64_t(offset) + before);
      const int shc = level[L].shift - ts + level[L].widthLog2;
      const int bx = gx >> shc, by = gy >> shc, bz = gz >> shc;
      if (L == 0) {
        const int slot = (bx & 1) | ((by & 1) << 1) | ((bz & 1) << 2);
        c.bx0[slot] = bx, c.by0[slot] = by, c.bz0[slot] = bz, c.block0[slot] = block;
      } else {
        c.kx[L] = bx, c.ky[L] = by, c.kz[L] = bz, c.block[L] = block;
      }
    }
  }

  // One voxel of the full-resolution volume (clamped to the volume), uncached: the point query
  // of section 3.1.
  VOXWALL_HD_INLINE std::uint32_t fetch(int x, int y, int z) const {
    RayCache c;
    int stop;
    return lookup(clampIndex(x, dimX), clampIndex(y, dimY), clampIndex(z, dimZ), 0, c, stop);
  }
  VOXWALL_HD_INLINE float voxel(int x, int y, int z) const { return scalar(fetch(x, y, z)); }
  // The same through a ray's cache of blocks (neighbouring voxels share their lookups).
  VOXWALL_HD_INLINE float voxel(int x, int y, int z, RayCache& rc) const {
    int stop;
    return scalar(
        lookup(clampIndex(x, dimX), clampIndex(y, dimY), clampIndex(z, dimZ), 0, rc, stop));
  }

  // Under pressure the CPU's decoded pages (node/page_cache.hpp) also hold level 1 (only where
  // levels > 1): its grid, looked up through the mip-map. Defined below SvmmLevelPages.
  SvmmLevelPages coarsePages() const;

#if !defined(__CUDA_ARCH__)
  // The CPU's decoded pages (node/page_decode.hpp) read base blocks whole, one walk down the
  // mip-map a block instead of a lookup a voxel: the base blocks' side, or 0 where the view has
  // one level (no blocks) or level 1's voxels are not base blocks.
  int baseBlockSide() const {
    return levels > 1 && level[1].shift == level[0].widthLog2 ? 1 << level[0].widthLog2 : 0;
  }
  // Base block (bx, by, bz)'s stored values, x fastest, baseBlockSide()^3 of them (only those of
  // voxels inside the volume are written). A block under a terminal voxel of a coarser level is
  // that voxel's value throughout: a level-1 voxel is one base block.
  void baseBlock(int bx, int by, int bz, std::uint32_t* out) const {
    const int wl = level[0].widthLog2, w = 1 << wl;
    RayCache c;
    int stop = 0;
    const std::uint32_t v = lookup(bx << wl, by << wl, bz << wl, 0, c, stop);
    const int nx = dimX - (bx << wl) < w ? dimX - (bx << wl) : w;
    const int ny = dimY - (by << wl) < w ? dimY - (by << wl) : w;
    const int nz = dimZ - (bz << wl) < w ? dimZ - (bz << wl) : w;
    const std::uint64_t b = c.block0[(bx & 1) | ((by & 1) << 1) | ((bz & 1) << 2)];
    for (int z = 0; z < nz; ++z)
      for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x) out[(z * w + y) * w + x] = stop > 0 ? v : base(b, x, y, z);
  }
#endif
  float coarseScale() const { return float(1 << level[1].shift); }

  // The level whose voxels are at most `footprint` voxels wide (0 when footprint < 2).
  VOXWALL_HD_INLINE int lodLevel(float footprint) const {
    int L = 0;
    while (L + 1 < levels && float(1 << level[L + 1].shift) <= footprint) ++L;
    return L;
  }

  // Fills c[8] with the corners of cell (ix, iy, iz) of level T (clamped to the level's grid)
  // and tells whether all eight came from one terminal voxel of level `stop` > T at level-stop
  // coordinates (vx, vy, vz).
  VOXWALL_HD_INLINE void corners(int ix, int iy, int iz, int T, RayCache& rc, float* c,
                                 bool& constant, int& stopOut, int& vx, int& vy, int& vz) const {
    const int sh = level[T].shift;
    const int mx = ((dimX - 1) >> sh), my = ((dimY - 1) >> sh), mz = ((dimZ - 1) >> sh);
    const int x1 = ix < mx ? ix + 1 : mx, y1 = iy < my ? iy + 1 : my, z1 = iz < mz ? iz + 1 : mz;
    int stop0 = 0, stop;
    const float v0 = scalar(lookup(ix, iy, iz, T, rc, stop0));
    const int d = level[stop0].shift - sh;
    constant =
        stop0 > T && (ix >> d) == (x1 >> d) && (iy >> d) == (y1 >> d) && (iz >> d) == (z1 >> d);
    stopOut = stop0, vx = ix >> d, vy = iy >> d, vz = iz >> d;
    if (constant) {
      for (int i = 0; i < 8; ++i) c[i] = v0;
      return;
    }
    c[0] = v0;
    if (stop0 == 0 && levels > 1) {
      // Base voxel: when the whole cell lies in its base block (three quarters of the cells for
      // w = 8), read the other corners from the block the lookup just cached.
      const int m = (1 << level[0].widthLog2) - 1;
      const int lx = ix & m, ly = iy & m, lz = iz & m;
      if (lx < m && ly < m && lz < m) {
        const int wl = level[0].widthLog2;
        const std::uint64_t b =
            rc.block0[((ix >> wl) & 1) | (((iy >> wl) & 1) << 1) | (((iz >> wl) & 1) << 2)];
        const int dx = x1 - ix, dy = y1 - iy, dz = z1 - iz;  // 0 at the volume's far edges
        c[1] = scalar(base(b, lx + dx, ly, lz));
        c[2] = scalar(base(b, lx, ly + dy, lz));
        c[3] = scalar(base(b, lx + dx, ly + dy, lz));
        c[4] = scalar(base(b, lx, ly, lz + dz));
        c[5] = scalar(base(b, lx + dx, ly, lz + dz));
        c[6] = scalar(base(b, lx, ly + dy, lz + dz));
        c[7] = scalar(base(b, lx + dx, ly + dy, lz + dz));
        return;
      }
    }
    c[1] = scalar(lookup(x1, iy, iz, T, rc, stop));
    c[2] = scalar(lookup(ix, y1, iz, T, rc, stop));
    c[3] = scalar(lookup(x1, y1, iz, T, rc, stop));
    c[4] = scalar(lookup(ix, iy, z1, T, rc, stop));
    c[5] = scalar(lookup(x1, iy, z1, T, rc, stop));
    c[6] = scalar(lookup(ix, y1, z1, T, rc, stop));
    c[7] = scalar(lookup(x1, y1, z1, T, rc, stop));
  }

  // A volume index-space position as a position on level T's grid (voxel centres on integers:
  // q = (p + 1/2) / 2^shift - 1/2), clamped to that grid.
  VOXWALL_HD_INLINE void toLevel(int T, float& x, float& y, float& z) const {
    const int sh = level[T].shift;
    const float P = float(1 << sh);
    if (T) x = (x + 0.5f) / P - 0.5f, y = (y + 0.5f) / P - 0.5f, z = (z + 0.5f) / P - 0.5f;
    const float mx = float((dimX - 1) >> sh), my = float((dimY - 1) >> sh),
                mz = float((dimZ - 1) >> sh);
    x = clampPosition(x, mx), y = clampPosition(y, my), z = clampPosition(z, mz);
  }

  // Sample at index-space (x, y, z): trilinear (or the nearest voxel when rc.nearest) on the
  // level rc.footprint selects. Also sets rc.region*: the box of positions with the same value.
  VOXWALL_HD_INLINE float sample(float x, float y, float z, RayCache& rc) const {
    const int T = rc.footprint >= 2.0f ? lodLevel(rc.footprint) : 0;
    const int sh = level[T].shift;
    toLevel(T, x, y, z);
    rc.regionFootprintMax = T + 1 < levels ? float(1 << level[T + 1].shift) : 3.0e38f;
    if (rc.nearest) {
      const int ix = int(x + 0.5f), iy = int(y + 0.5f), iz = int(z + 0.5f);
      int stop;
      const float v = scalar(lookup(ix, iy, iz, T, rc, stop));
      rc.il = T;  // the level gradients use (rc.ix stays -1: no cell corners in this mode)
      const int d = level[stop].shift - sh;
      setRegion(rc, T, ix >> d << d, iy >> d << d, iz >> d << d, 1 << d, -0.5f);
      return v;
    }
    const int ix = int(x), iy = int(y), iz = int(z);
    if (ix != rc.ix || iy != rc.iy || iz != rc.iz || T != rc.il) {
      int stop, vx, vy, vz;
      corners(ix, iy, iz, T, rc, rc.c, rc.cellConstant, stop, vx, vy, vz);
      rc.ix = ix, rc.iy = iy, rc.iz = iz, rc.il = T;
      rc.cellStop = stop, rc.cellVx = vx, rc.cellVy = vy, rc.cellVz = vz;
    }
    if (rc.cellConstant) {
      // Every cell whose lower corner lies in [lo, hi - 1) of the terminal voxel's box reads
      // only that voxel.
      const int d = level[rc.cellStop].shift - sh;
      setRegion(rc, T, rc.cellVx << d, rc.cellVy << d, rc.cellVz << d, 1 << d, 0.0f, true);
      return rc.c[0];
    }
    rc.regionValid = false;
    const float tx = x - float(ix), ty = y - float(iy), tz = z - float(iz);
    return blendCorners(rc.c, tx, ty, tz);
  }

  // The region of level-T voxels [v, v + n) per axis as full-resolution index-space positions:
  // level-T position q maps to (q + 1/2) 2^shift - 1/2. Trilinear cells need their upper corner
  // inside too (hence hi - 1); sides on the volume's border extend to infinity since positions
  // there are clamped. A 1/64-voxel margin keeps rounding from admitting a position outside.
  VOXWALL_HD_INLINE void setRegion(RayCache& rc, int T, int vx, int vy, int vz, int n,
                                   float nearestShift, bool trilinear = false) const {
    const int sh = level[T].shift;
    const float P = float(1 << sh);
    const int v[3] = {vx, vy, vz};
    const int m[3] = {(dimX - 1) >> sh, (dimY - 1) >> sh, (dimZ - 1) >> sh};
    for (int a = 0; a < 3; ++a) {
      const float lo = float(v[a]) + nearestShift;
      const float hi = float(v[a] + n) + nearestShift - (trilinear ? 1.0f : 0.0f);
      rc.regionLo[a] = v[a] <= 0 ? -3.0e38f : (lo + 0.5f) * P - 0.5f + 1.0f / 64.0f;
      rc.regionHi[a] = v[a] + n > m[a] ? 3.0e38f : (hi + 0.5f) * P - 0.5f - 1.0f / 64.0f;
    }
    rc.regionValid = true;
  }

  VOXWALL_HD_INLINE float sample(float x, float y, float z) const {
    RayCache rc;
    return sample(x, y, z, rc);
  }

  // The 24 full-resolution voxels around a cell that cornerDifferences reads.
  struct Around {
    const SvmmView* view;
    RayCache* rc;
    int ix, iy, iz;
    VOXWALL_HD_INLINE float operator()(int ox, int oy, int oz) const {
      int stop;
      return view->scalar(view->lookup(clampIndex(ix + ox, view->dimX),
                                       clampIndex(iy + oy, view->dimY),
                                       clampIndex(iz + oz, view->dimZ), 0, *rc, stop));
    }
  };

  // The gradient hook (GradientView), on full-resolution trilinear samples only: a coarser
  // level's or a nearest sample's gradient stays the six samples it always was.
  VOXWALL_HD_INLINE bool gradient(float x, float y, float z, RayCache& rc, float* g) const {
    if (rc.il != 0 || rc.nearest ||
        outsideGrid(x, y, z, float(dimX - 1), float(dimY - 1), float(dimZ - 1)))
      return false;
    const int ix = int(x), iy = int(y), iz = int(z);
    if (!rc.grad.holds(ix, iy, iz)) {
      cornerDifferences(rc.c, Around{this, &rc, ix, iy, iz}, rc.grad.d);
      rc.grad.ix = ix, rc.grad.iy = iy, rc.grad.iz = iz;
    }
    rc.grad.blend(x - float(ix), y - float(iy), z - float(iz), g);
    return true;
  }

  // A gradient neighbour on the current sample's level; leaves the cell and region alone.
  VOXWALL_HD_INLINE float sampleNear(float x, float y, float z, RayCache& rc) const {
    const int T = rc.il < 0 ? 0 : rc.il;
    toLevel(T, x, y, z);
    const int ix = int(x), iy = int(y), iz = int(z);
    float c[8];
    const int dx = ix - rc.ix, dy = iy - rc.iy, dz = iz - rc.iz;
    if (rc.il == T && (dx == 1 || dx == -1) + (dy == 1 || dy == -1) + (dz == 1 || dz == -1) == 1 &&
        (dx == 0) + (dy == 0) + (dz == 0) == 2) {
      // A neighbouring cell (central differences step one voxel along one axis): it shares a
      // face with the sample's cell, so only the four corners of the far face are looked up.
      // Corner i is at (ix + (i & 1), iy + (i >> 1 & 1), iz + (i >> 2)), clamped.
      const int a = dx ? 0 : (dy ? 1 : 2), bit = 1 << a, d = dx + dy + dz;
      const int sh2 = level[T].shift;
      const int m[3] = {(dimX - 1) >> sh2, (dimY - 1) >> sh2, (dimZ - 1) >> sh2};
      const int lo[3] = {ix, iy, iz};
      int stop;
      for (int i = 0; i < 8; ++i) {
        const bool far = d > 0 ? (i & bit) : !(i & bit);
        if (!far) {
          c[i] = rc.c[i ^ bit];  // the shared face: the sample cell's opposite corner
          continue;
        }
        int q[3];
        for (int k = 0; k < 3; ++k) {
          const int v = lo[k] + ((i >> k) & 1);
          q[k] = v < m[k] ? v : m[k];
        }
        c[i] = scalar(lookup(q[0], q[1], q[2], T, rc, stop));
      }
    } else {
      bool constant;
      int stop, vx, vy, vz;
      corners(ix, iy, iz, T, rc, c, constant, stop, vx, vy, vz);
    }
    const float tx = x - float(ix), ty = y - float(iy), tz = z - float(iz);
    return blendCorners(c, tx, ty, tz);
  }
};

static_assert(std::is_trivially_copyable_v<SvmmView>);

// svmm's level `T` as the CPU's decoded pages take a level: its grid's size and voxels (looked up
// through the mip-map, as the view's own samples at that level read them).
struct SvmmLevelPages {
  const SvmmView* view = nullptr;
  int T = 1;
  int dimX = 1, dimY = 1, dimZ = 1;
  float maxX = 0, maxY = 0, maxZ = 0;
  std::uint64_t cacheId = 0;
  using RayCache = SvmmView::RayCache;
  float voxel(int x, int y, int z, RayCache& rc) const {
    int stop;
    return view->scalar(view->lookup(x, y, z, T, rc, stop));
  }
};

inline SvmmLevelPages SvmmView::coarsePages() const {
  SvmmLevelPages l;
  l.view = this;
  const int sh = level[1].shift;
  l.dimX = ((dimX - 1) >> sh) + 1, l.dimY = ((dimY - 1) >> sh) + 1, l.dimZ = ((dimZ - 1) >> sh) + 1;
  l.maxX = float(l.dimX - 1), l.maxY = float(l.dimY - 1), l.maxZ = float(l.dimZ - 1);
  l.cacheId = cacheId;
  return l;
}

}  // namespace voxwall::codec::kernels
