// SVMM encoder (layout.cpp reads the files back). The format is documented in svmm_codec.hpp.
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <glm/common.hpp>
#include <limits>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>

#include "format.hpp"

namespace voxwall::codec::svmm {

using kernels::kSvmmDensity16;
using kernels::kSvmmDensity8;
using kernels::kSvmmRgba32;
using kernels::kSvmmTerminal;

double deltaForQuality(int quality, int channels) {
  if (quality < 0 || quality > 100) throw std::invalid_argument("quality must be in 0..100");
  return std::sqrt(double(channels)) * (1.0 - double(quality) / 100.0);
}

namespace {

using kernels::svmmBaseBytes;
using kernels::svmmWordBytes;
int channelsOf(int format) { return format == kSvmmRgba32 ? 4 : 1; }

// The value a non-base word of `format` stores for `v` (RGBA: alpha to 3 bits and back).
std::uint32_t storedNonBase(int format, std::uint32_t v) {
  if (format != kSvmmRgba32) return v;
  const std::uint32_t a3 = ((v >> 24) * 7u + 127u) / 255u;
  return (v & 0x00ffffffu) | (kernels::svmmExpandAlpha3(a3) << 24);
}

std::uint32_t packWord(int format, std::uint32_t v, bool terminal, std::uint32_t nibble) {
  const std::uint32_t low = (terminal ? kSvmmTerminal : 0u) | nibble;
  if (format == kSvmmDensity8) return (v << 8) | low;
  if (format == kSvmmDensity16) return (v << 16) | low;
  const std::uint32_t a3 = ((v >> 24) * 7u + 127u) / 255u;
  return ((v & 255u) << 24) | (((v >> 8) & 255u) << 16) | (((v >> 16) & 255u) << 8) | (a3 << 5) |
         low;
}

std::uint64_t distance2(int format, std::uint32_t a, std::uint32_t b) {
  if (format != kSvmmRgba32) {
    const std::int64_t d = std::int64_t(a) - std::int64_t(b);
    return std::uint64_t(d * d);
  }
  std::uint64_t s = 0;
  for (int c = 0; c < 4; ++c) {
    const std::int64_t d =
        std::int64_t((a >> (8 * c)) & 255u) - std::int64_t((b >> (8 * c)) & 255u);
    s += std::uint64_t(d * d);
  }
  return s;
}

// One level while encoding: values (biased scalars or packed RGBA) and terminal flags over the
// padded grid; `logical` voxels overlap the volume.
struct Grid {
  glm::ivec3 logical{0}, padded{0};
  std::vector<std::uint32_t> value;
  std::vector<std::uint8_t> terminal;  // empty: every voxel is terminal (level 0)
  // Level 0 is a window of slices z0 .. of the input, read from its own storage through `read`
  // (no copy of 4 bytes per voxel; at() takes volume coordinates); `value` is then empty.
  const void* base = nullptr;
  std::uint32_t (*read)(const void*, std::size_t) = nullptr;
  int z0 = 0;
  std::uint32_t get(std::size_t i) const { return base ? read(base, i) : value[i]; }
  std::size_t at(int x, int y, int z) const {
    return (std::size_t(z - z0) * std::size_t(padded.y) + std::size_t(y)) * std::size_t(padded.x) +
           std::size_t(x);
  }
  bool inside(glm::ivec3 g) const { return g.x < padded.x && g.y < padded.y && g.z < padded.z; }
  std::uint32_t valueAt(glm::ivec3 g) const { return inside(g) ? get(at(g.x, g.y, g.z)) : 0u; }
  bool terminalAt(glm::ivec3 g) const {
    return !inside(g) || terminal.empty() || terminal[at(g.x, g.y, g.z)];
  }
};

// Level i + 1 over level i's `logical` voxels (blocks of w^3), every voxel terminal and zero.
Grid emptyLevel(glm::ivec3 fineLogical, int w) {
  Grid g;
  g.logical = (fineLogical + w - 1) / w;
  g.padded = evenUp(g.logical);
  g.value.assign(count3(g.padded), 0);
  g.terminal.assign(count3(g.padded), 1);
  return g;
}

// Rows zBegin .. zEnd - 1 of level i + 1 (`g`) from level i (`fine`, which holds at least the
// slices under those rows).
void buildRows(const Grid& fine, Grid& g, int w, int format, double threshold2, int zBegin,
               int zEnd, int threads, Progress& progress) {
  const int channels = channelsOf(format);
  parallelFor(std::size_t(zEnd - zBegin), threads, [&](std::size_t zi) {
    const int z = zBegin + int(zi);
    for (int y = 0; y < g.logical.y; ++y)
      for (int x = 0; x < g.logical.x; ++x) {
        const glm::ivec3 lo(x * w, y * w, z * w);
        const glm::ivec3 hi = glm::min(lo + w, fine.logical);
        std::uint64_t sum[4] = {0, 0, 0, 0}, n = 0;
        bool allTerminal = true;
        for (int fz = lo.z; fz < hi.z; ++fz)
          for (int fy = lo.y; fy < hi.y; ++fy)
            for (int fx = lo.x; fx < hi.x; ++fx) {
              const std::size_t i = fine.at(fx, fy, fz);
              const std::uint32_t v = fine.get(i);
              if (!fine.terminal.empty() && !fine.terminal[i]) allTerminal = false;
              if (channels == 1) {
                sum[0] += v;
              } else {
                for (int c = 0; c < 4; ++c) sum[c] += (v >> (8 * c)) & 255u;
              }
              ++n;
            }
        std::uint32_t avg = 0;
        if (channels == 1) {
          avg = std::uint32_t((sum[0] + n / 2) / n);
        } else {
          for (int c = 0; c < 4; ++c) avg |= std::uint32_t((sum[c] + n / 2) / n) << (8 * c);
        }
        const std::uint32_t stored = storedNonBase(format, avg);
        bool homogeneous = allTerminal;
        for (int fz = lo.z; homogeneous && fz < hi.z; ++fz)
          for (int fy = lo.y; homogeneous && fy < hi.y; ++fy)
            for (int fx = lo.x; fx < hi.x; ++fx)
              if (double(distance2(format, fine.get(fine.at(fx, fy, fz)), stored)) > threshold2) {
                homogeneous = false;
                break;
              }
        const std::size_t i = g.at(x, y, z);
        g.value[i] = stored;
        g.terminal[i] = homogeneous;
      }
    progress.advance();
  });
}

// v's low `bytes` bytes, little-endian, at o.
void storeValue(std::byte* o, std::uint32_t v, int bytes) {
  for (int b = 0; b < bytes; ++b) o[b] = std::byte((v >> (8 * b)) & 255u);
}

void putValue(std::vector<std::byte>& out, std::uint32_t v, int bytes) {
  out.resize(out.size() + std::size_t(bytes));
  storeValue(out.data() + out.size() - std::size_t(bytes), v, bytes);
}

template <class T, int Bias>
std::uint32_t readBiased(const void* voxels, std::size_t i) {
  return std::uint32_t(int(static_cast<const T*>(voxels)[i]) + Bias);
}

std::uint32_t readWord(const void* voxels, std::size_t i) {
  return static_cast<const std::uint32_t*>(voxels)[i];
}

// Level 0, a slab of z-slices at a time: window(z0, count, buffer) gives slices z0 ..
// z0 + count - 1 (inside the volume) as a Grid, read into `buffer` where they are not in memory.
struct Input {
  glm::ivec3 dims;
  int format;
  int bias;
  double peak;
  std::function<Grid(int z0, int count, std::vector<std::byte>& buffer)> window;
  std::size_t sliceBytes = 0;  // of the window's storage
  bool scalar = true;          // the PSNR of scalar data is summed while the base is written
};

// How many rows of a level built from level 0 (blocks w wide) to read at once: a window of
// about `windowBytes`, at least one row.
int rowsPerWindow(const Input& in, int w, std::size_t windowBytes) {
  const std::size_t row = std::max<std::size_t>(1, in.sliceBytes * std::size_t(w));
  return int(std::clamp<std::size_t>(windowBytes / row, 1, 1 << 20));
}

// The mip-map: the grid of every level (0: only its size; the input is read a slab at a time),
// the block widths and shifts, and, once written, each level's block count and place in the data
// section.
struct Levels {
  std::vector<Grid> grids;
  std::vector<int> widths, shifts{0};
  int n = 1;
  glm::ivec3 rootGrid{};
  std::vector<std::uint64_t> blocks, offsets, lengths;
};

// Level 1 from the input, a window of slices at a time.
Grid buildLevelOne(const Input& in, int w, double threshold2, const Params& p, Progress& progress) {
  Grid g = emptyLevel(in.dims, w);
  const int step = rowsPerWindow(in, w, p.windowBytes);
  std::vector<std::byte> buffer;
  for (int r0 = 0; r0 < g.logical.z; r0 += step) {
    const int r1 = std::min(g.logical.z, r0 + step);
    const int z0 = r0 * w;
    const Grid fine = in.window(z0, std::min(in.dims.z, r1 * w) - z0, buffer);
    buildRows(fine, g, w, in.format, threshold2, r0, r1, p.threads, progress);
  }
  return g;
}

// Level after level, until one fits in the root width (the top).
Levels buildLevels(const Input& in, const Params& p, double threshold2, Progress& progress) {
  Levels lv;
  lv.grids.resize(1);
  lv.grids[0].logical = lv.grids[0].padded = in.dims;
  while (maxOf(lv.grids.back().logical) > p.rootWidth) {
    if (int(lv.grids.size()) == kernels::kSvmmMaxLevels)
      throw std::invalid_argument("more than 16 mip levels: raise the root width");
    const int i = int(lv.grids.size()) - 1;
    const int w = p.stepped ? std::min(2 << i, 256) : p.blockWidth;
    const glm::ivec3 next = (lv.grids.back().logical + w - 1) / w;
    progress.begin("svmm: level " + std::to_string(i + 1), std::uint64_t(next.z));
    if (i == 0) {
      lv.grids.push_back(buildLevelOne(in, w, threshold2, p, progress));
    } else {
      Grid g = emptyLevel(lv.grids.back().logical, w);
      buildRows(lv.grids.back(), g, w, in.format, threshold2, 0, g.logical.z, p.threads, progress);
      lv.grids.push_back(std::move(g));
    }
    progress.end();
    lv.widths.push_back(w);
    lv.shifts.push_back(lv.shifts.back() + std::countr_zero(unsigned(w)));
    if (lv.shifts.back() > 30) throw std::invalid_argument("mipmap factor over 2^30");
  }
  lv.n = int(lv.grids.size());
  lv.widths.push_back(0);
  lv.blocks.assign(std::size_t(lv.n), 0);
  lv.blocks[std::size_t(lv.n - 1)] = 1;
  lv.offsets.assign(std::size_t(lv.n), 0), lv.lengths.assign(std::size_t(lv.n), 0);
  lv.rootGrid = lv.n == 1 ? in.dims : lv.grids.back().padded;
  return lv;
}

// Where the children of a level's blocks go: their origins (for the next level to write), or,
// for the base level's blocks, only their count.
struct Children {
  std::vector<glm::ivec3>* origins = nullptr;
  std::uint64_t count = 0;
  void add(glm::ivec3 origin) {
    if (origins) origins->push_back(origin);
    ++count;
  }
};

// One block of level L at `origin` (level-L voxels) of `size` voxels, as words: value, terminal
// bit and the offset nibble of its children's first block in level L - 1, which are added to
// `next`.
void writeBlock(const Levels& lv, int L, glm::ivec3 origin, glm::ivec3 size, int format,
                Children& next, std::vector<std::uint32_t>& words) {
  const Grid& G = lv.grids[std::size_t(L)];
  const int childW = lv.widths[std::size_t(L - 1)];
  for (int bz = 0; bz < size.z; bz += 2)
    for (int by = 0; by < size.y; by += 2)
      for (int bx = 0; bx < size.x; bx += 2) {
        const std::uint64_t first = next.count;
        bool term[8];
        for (int j = 0; j < 8; ++j) {
          const glm::ivec3 g = origin + glm::ivec3(bx + (j & 1), by + (j >> 1 & 1), bz + (j >> 2));
          term[j] = G.terminalAt(g);
          if (!term[j]) next.add(g * childW);
        }
        if (next.count > std::numeric_limits<std::uint32_t>::max())
          throw std::invalid_argument("a level has more than 2^32 blocks");
        const std::uint32_t off = next.count > first ? std::uint32_t(first) : 0u;
        for (int j = 0; j < 8; ++j) {
          const glm::ivec3 l(bx + (j & 1), by + (j >> 1 & 1), bz + (j >> 2));
          words[(std::size_t(l.z) * std::size_t(size.y) + std::size_t(l.y)) * std::size_t(size.x) +
                std::size_t(l.x)] =
              packWord(format, G.valueAt(origin + l), term[j], (off >> (4 * j)) & 15u);
        }
      }
}

// Level 1's blocks: the root grid when level 1 is the top, else one block under each level-2
// voxel; and, once level 1 is written, the index of each one's first child in the base level.
struct LevelOneBlocks {
  glm::ivec3 size{0}, grid{1};  // block size in level-1 voxels; blocks per axis
  std::vector<std::uint64_t> firstChild;
  explicit LevelOneBlocks(const Levels& lv) {
    if (lv.n == 2) {
      size = lv.rootGrid;
    } else {
      size = glm::ivec3(lv.widths[1]);
      grid = lv.grids[2].padded;
    }
    firstChild.assign(count3(grid), 0);
  }
  std::size_t index(glm::ivec3 b) const {
    return (std::size_t(b.z) * std::size_t(grid.y) + std::size_t(b.y)) * std::size_t(grid.x) +
           std::size_t(b.x);
  }
};

// Levels top .. 1, in tree order, into the data section (each 8-byte aligned); records where
// each level-1 block's children start in the base level.
void writeUpperLevels(Levels& lv, int format, LevelOneBlocks& one, std::vector<std::byte>& data,
                      Progress& progress) {
  const int top = lv.n - 1, ws = svmmWordBytes(format);
  std::vector<std::vector<std::byte>> out(static_cast<std::size_t>(lv.n));
  std::vector<glm::ivec3> cur{glm::ivec3(0)};  // block origins of level L, in level-L voxels
  for (int L = top; L >= 1; --L) {
    const glm::ivec3 size = L == top ? lv.rootGrid : glm::ivec3(lv.widths[std::size_t(L)]);
    std::vector<glm::ivec3> nextOrigins;
    Children next;
    if (L > 1) next.origins = &nextOrigins;
    std::vector<std::uint32_t> words(count3(size));
    auto& o = out[std::size_t(L)];
    o.reserve(cur.size() * words.size() * std::size_t(ws));
    for (const glm::ivec3 origin : cur) {
      if (L == 1) one.firstChild[one.index(origin / one.size)] = next.count;
      writeBlock(lv, L, origin, size, format, next, words);
      for (const std::uint32_t w : words) putValue(o, w, ws);
    }
    lv.blocks[std::size_t(L - 1)] = next.count;
    cur = std::move(nextOrigins);
    progress.advance();
  }
  for (int L = top; L >= 1; --L) {
    while (data.size() % 8) data.push_back(std::byte{0});
    lv.offsets[std::size_t(L)] = data.size();
    lv.lengths[std::size_t(L)] = out[std::size_t(L)].size();
    data.insert(data.end(), out[std::size_t(L)].begin(), out[std::size_t(L)].end());
    std::vector<std::byte>().swap(out[std::size_t(L)]);
  }
}

// A base block's 2^3 group as stored with --base-compression: a byte of occupancy and the mean of
// the occupied voxels. Returns the squared error of the occupied voxels (unoccupied ones decode
// to their zero).
double writeCompressedGroup(const Grid& G, glm::ivec3 corner, int format, std::byte* o) {
  const int channels = channelsOf(format);
  std::uint32_t bitmap = 0, values[8] = {};
  std::uint64_t sum[4] = {0, 0, 0, 0}, cnt = 0;
  for (int j = 0; j < 8; ++j) {
    const glm::ivec3 q = corner + glm::ivec3(j & 1, j >> 1 & 1, j >> 2);
    const bool in = q.x < G.logical.x && q.y < G.logical.y && q.z < G.logical.z;
    const std::uint32_t v = in ? G.get(G.at(q.x, q.y, q.z)) : 0u;
    const bool occupied = format == kSvmmRgba32 ? (v >> 24) != 0 : v != 0;
    if (!occupied) continue;
    bitmap |= 1u << j;
    values[cnt++] = v;
    if (channels == 1)
      sum[0] += v;
    else
      for (int c = 0; c < 4; ++c) sum[c] += (v >> (8 * c)) & 255u;
  }
  std::uint32_t mean = 0;
  if (cnt) {
    if (channels == 1)
      mean = std::uint32_t((sum[0] + cnt / 2) / cnt);
    else
      for (int c = 0; c < 4; ++c) mean |= std::uint32_t((sum[c] + cnt / 2) / cnt) << (8 * c);
  }
  o[0] = std::byte(bitmap);
  storeValue(o + 1, mean, svmmBaseBytes(format));
  double squares = 0;
  for (std::uint64_t i = 0; channels == 1 && i < cnt; ++i) {
    const double d = double(values[i]) - double(mean);
    squares += d * d;
  }
  return squares;
}

// The base level without levels above it: the whole grid, x fastest, a window at a time.
void writeWholeBase(const Input& in, std::size_t windowBytes, std::vector<std::byte>& data,
                    Progress& progress) {
  const int bs = svmmBaseBytes(in.format);
  const std::size_t slice = std::size_t(in.dims.x) * std::size_t(in.dims.y);
  const int step = rowsPerWindow(in, 1, windowBytes);
  data.reserve(data.size() + count3(in.dims) * std::size_t(bs) + 8);  // + the 8 zero bytes
  std::vector<std::byte> buffer;
  for (int z0 = 0; z0 < in.dims.z; z0 += step) {
    const int count = std::min(step, in.dims.z - z0);
    const Grid G = in.window(z0, count, buffer);
    for (std::size_t i = 0; i < slice * std::size_t(count); ++i) putValue(data, G.get(i), bs);
    progress.advance(std::uint64_t(count));
  }
}

// Bytes of a base block w wide: its voxels, or its groups' bitmaps and values.
std::size_t baseBlockBytes(int w, int format, bool compressBase) {
  const std::size_t bs = std::size_t(svmmBaseBytes(format));
  const std::size_t side = std::size_t(compressBase ? w / 2 : w);
  return side * side * side * (compressBase ? 1 + bs : bs);
}

// The squared error of the voxels under the terminal level-1 voxel c (the window G holds them):
// they decode to the value of c's highest terminal ancestor.
double leafSquares(const Levels& lv, const Grid& G, glm::ivec3 c) {
  const int w = lv.widths[0];
  const glm::ivec3 v = c * w, end = glm::min(v + w, G.logical);
  int L = 1;
  while (L + 1 < lv.n && lv.grids[std::size_t(L + 1)].terminalAt(c / lv.widths[std::size_t(L)])) {
    c /= lv.widths[std::size_t(L)];
    ++L;
  }
  const double value = double(lv.grids[std::size_t(L)].valueAt(c));
  double squares = 0;
  for (int z = v.z; z < end.z; ++z)
    for (int y = v.y; y < end.y; ++y)
      for (int x = v.x; x < end.x; ++x) {
        const double d = double(G.get(G.at(x, y, z))) - value;
        squares += d * d;
      }
  return squares;
}

// The base block w wide at voxel v (the window G holds it) into `o`; its squared error.
double writeBaseBlock(const Grid& G, glm::ivec3 v, int w, int format, bool compressBase,
                      std::byte* o) {
  const int bs = svmmBaseBytes(format);
  double squares = 0;
  if (compressBase) {
    for (int gz = 0; gz < w; gz += 2)
      for (int gy = 0; gy < w; gy += 2)
        for (int gx = 0; gx < w; gx += 2, o += 1 + bs)
          squares += writeCompressedGroup(G, v + glm::ivec3(gx, gy, gz), format, o);
    return squares;
  }
  for (int z = 0; z < w; ++z)
    for (int y = 0; y < w; ++y)
      for (int x = 0; x < w; ++x, o += bs) {
        const glm::ivec3 q = v + glm::ivec3(x, y, z);
        const bool inside = q.x < G.logical.x && q.y < G.logical.y && q.z < G.logical.z;
        storeValue(o, inside ? G.get(G.at(q.x, q.y, q.z)) : 0u, bs);
      }
  return squares;
}

// The base level's blocks: the children of level 1's non-terminal voxels, in tree order. A block's
// place follows from its level-1 block's first child and the non-terminal voxels before it in
// that block, which are walked a 2-voxel layer (z) at a time: so the input is read once, a slab of
// 2 w0 slices at a time, and every block is written where it belongs. Returns the squared error
// of the decoded voxels against the input (scalar data; 0 for RGBA).
double writeBlockedBase(const Input& in, const Levels& lv, const LevelOneBlocks& one,
                        bool compressBase, std::byte* base, int threads, Progress& progress) {
  const Grid& G1 = lv.grids[1];
  const int w = lv.widths[0];
  const std::size_t blockBytes = baseBlockBytes(w, in.format, compressBase);
  const std::size_t blocksPerLayer = std::size_t(one.grid.x) * std::size_t(one.grid.y);
  std::vector<std::uint64_t> nextChild(blocksPerLayer);
  std::vector<double> squares(blocksPerLayer);
  std::vector<std::byte> buffer;
  double total = 0;
  for (int z1 = 0; z1 < G1.logical.z; z1 += 2) {
    const int bz = z1 / one.size.z, lz = z1 % one.size.z;
    const Grid G = in.window(z1 * w, std::min(in.dims.z, (z1 + 2) * w) - z1 * w, buffer);
    parallelFor(blocksPerLayer, threads, [&](std::size_t b) {
      const glm::ivec3 block(int(b % std::size_t(one.grid.x)), int(b / std::size_t(one.grid.x)),
                             bz);
      const glm::ivec3 origin = block * one.size;
      if (lz == 0) nextChild[b] = one.firstChild[one.index(block)];
      double sq = 0;
      for (int by = 0; by < one.size.y; by += 2)
        for (int bx = 0; bx < one.size.x; bx += 2)
          for (int j = 0; j < 8; ++j) {
            const glm::ivec3 c =
                origin + glm::ivec3(bx + (j & 1), by + (j >> 1 & 1), lz + (j >> 2));
            if (c.x >= G1.logical.x || c.y >= G1.logical.y || c.z >= G1.logical.z) continue;
            if (!G1.terminalAt(c))
              sq += writeBaseBlock(G, c * w, w, in.format, compressBase,
                                   base + nextChild[b]++ * blockBytes);
            else if (in.scalar)
              sq += leafSquares(lv, G, c);
          }
      squares[b] = sq;
    });
    for (const double sq : squares) total += sq;  // in block order: the same sum on any threads
    progress.advance();
  }
  return in.scalar ? total : 0.0;
}

std::vector<std::byte> paramsSection(const Input& in, const Params& p, const Levels& lv,
                                     bool compressBase, double delta, double psnrValue) {
  std::vector<std::byte> params;
  ByteWriter w(params);
  w.put<std::uint32_t>(std::uint32_t(in.format));
  w.put<std::uint32_t>(compressBase ? kBlockCompressed : 0u);
  w.put<std::int32_t>(in.bias);
  w.put<std::uint32_t>(std::uint32_t(p.quality));
  w.put<double>(delta);
  w.put<double>(in.peak);
  w.put<std::uint32_t>(std::uint32_t(p.rootWidth));
  w.put<std::uint32_t>(p.stepped ? 1u : 0u);
  w.put<std::uint32_t>(std::uint32_t(lv.n));
  w.put<std::uint32_t>(std::uint32_t(lv.rootGrid.x));
  w.put<std::uint32_t>(std::uint32_t(lv.rootGrid.y));
  w.put<std::uint32_t>(std::uint32_t(lv.rootGrid.z));
  for (int i = 0; i < lv.n; ++i) {
    w.put<std::uint32_t>(std::uint32_t(lv.widths[std::size_t(i)]));
    w.put<std::uint32_t>(std::uint32_t(lv.shifts[std::size_t(i)]));
    w.put<std::uint64_t>(lv.blocks[std::size_t(i)]);
    w.put<std::uint64_t>(lv.offsets[std::size_t(i)]);
    w.put<std::uint64_t>(lv.lengths[std::size_t(i)]);
  }
  w.put<double>(psnrValue);
  return params;
}

// `measure` gives the PSNR of a non-scalar (RGBA) file; a scalar file's comes from the squared
// errors summed while its base level is written (`reference` gives its peak).
CompressedVolume encodeInput(const Input& in, VolumeInfo info, const Params& p, Progress& progress,
                             EncodeStats* stats, const Volume& reference,
                             const std::function<double(const CompressedVolume&)>& measure) {
  if (p.rootWidth < 2) throw std::invalid_argument("root width must be at least 2");
  if (!p.stepped &&
      (p.blockWidth < 2 || p.blockWidth > 64 || !std::has_single_bit(unsigned(p.blockWidth))))
    throw std::invalid_argument("block width must be a power of two in 2..64");
  const double delta = deltaForQuality(p.quality, channelsOf(in.format));
  const double thr = delta * in.peak;
  Levels lv = buildLevels(in, p, thr * thr, progress);
  const bool compressBase = p.baseCompression && lv.n > 1;

  std::vector<std::byte> data;
  double squares = 0;
  if (lv.n == 1) {
    progress.begin("svmm: writing the base level", std::uint64_t(in.dims.z));
    writeWholeBase(in, p.windowBytes, data, progress);
  } else {
    progress.begin("svmm: writing levels", std::uint64_t(lv.n - 1));
    LevelOneBlocks one(lv);
    writeUpperLevels(lv, in.format, one, data, progress);
    progress.end();
    while (data.size() % 8) data.push_back(std::byte{0});
    lv.offsets[0] = data.size();
    const std::size_t blockBytes = baseBlockBytes(lv.widths[0], in.format, compressBase);
    data.reserve(lv.offsets[0] + lv.blocks[0] * blockBytes + 8);  // + the 8 zero bytes at the end
    data.resize(lv.offsets[0] + lv.blocks[0] * blockBytes);
    progress.begin("svmm: writing the base level", std::uint64_t(lv.grids[1].logical.z + 1) / 2);
    squares = writeBlockedBase(in, lv, one, compressBase, data.data() + lv.offsets[0], p.threads,
                               progress);
  }
  progress.end();
  lv.lengths[0] = data.size() - lv.offsets[0];
  for (int i = 0; i < 8; ++i) data.push_back(std::byte{0});

  CompressedVolume cv;
  cv.info = info;
  cv.sections.emplace_back(kParams, paramsSection(in, p, lv, compressBase, delta, 0.0));
  cv.sections.emplace_back(kData, std::move(data));
  double psnrValue = 0;
  if (in.scalar) {
    PsnrSum sum(reference);
    sum.addSquares(squares, count3(in.dims));
    psnrValue = sum.psnr();
  } else {
    progress.begin("svmm: measuring PSNR", 1);
    psnrValue = measure(cv);
    progress.advance();
    progress.end();
  }
  cv.sections[0].second = paramsSection(in, p, lv, compressBase, delta, psnrValue);
  if (stats) {
    stats->levels = lv.n;
    stats->blocks = lv.blocks;
    stats->widths = lv.widths;
    stats->dataBytes = cv.sections[1].second.size();
    stats->delta = delta;
    stats->psnr = psnrValue;
  }
  return cv;
}

}  // namespace

CompressedVolume encode(const VolumeSource& source, const Params& params, Progress& progress,
                        EncodeStats* stats) {
  Input in;
  in.dims = source.dims;
  in.bias = 0;
  switch (source.type) {
    case ScalarType::UInt8:
      in.format = kSvmmDensity8;
      break;
    case ScalarType::UInt16:
      in.format = kSvmmDensity16;
      break;
    case ScalarType::Int16:
      in.format = kSvmmDensity16;
      in.bias = kInt16Bias;
      break;
    default:
      throw std::invalid_argument("svmm codes uint8, uint16 and int16 volumes, not " +
                                  std::string(scalarName(source.type)));
  }
  in.peak = source.valueMax - source.valueMin;
  if (!(in.peak > 0)) in.peak = 1;
  in.sliceBytes = source.sliceBytes();
  const auto read = source.type == ScalarType::UInt8    ? &readBiased<std::uint8_t, 0>
                    : source.type == ScalarType::UInt16 ? &readBiased<std::uint16_t, 0>
                                                        : &readBiased<std::int16_t, kInt16Bias>;
  const Volume* whole = source.inMemory();
  in.window = [&source, whole, read](int z0, int count, std::vector<std::byte>& buffer) {
    Grid g;
    g.logical = g.padded = source.dims;
    g.read = read, g.z0 = z0;
    if (whole) {
      g.base = whole->data.data() + std::size_t(z0) * source.sliceBytes();
    } else {
      buffer.resize(std::size_t(count) * source.sliceBytes());
      source.readSlices(z0, count, buffer);
      g.base = buffer.data();
    }
    return g;
  };
  const Volume header = source.headerVolume();
  return encodeInput(in, volumeInfo(header, SvmmCodecEntry::kId), params, progress, stats, header,
                     nullptr);
}

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats) {
  return encode(*memorySource(volume), params, progress, stats);
}

CompressedVolume encodeRgba(const RgbaVolume& volume, const Params& params, Progress& progress,
                            EncodeStats* stats) {
  if (volume.dims.x < 1 || volume.dims.y < 1 || volume.dims.z < 1 ||
      volume.rgba.size() != count3(volume.dims))
    throw std::invalid_argument("RGBA volume: voxel count does not match its dimensions");
  Input in;
  in.dims = volume.dims;
  in.format = kSvmmRgba32;
  in.bias = 0;
  in.peak = 255;
  in.scalar = false;
  in.sliceBytes = std::size_t(volume.dims.x) * std::size_t(volume.dims.y) * 4;
  in.window = [&volume](int z0, int, std::vector<std::byte>&) {
    Grid g;
    g.logical = g.padded = volume.dims;
    g.read = &readWord, g.z0 = z0;
    g.base = volume.rgba.data() +
             std::size_t(z0) * std::size_t(volume.dims.x) * std::size_t(volume.dims.y);
    return g;
  };
  VolumeInfo info;
  info.codec = SvmmCodecEntry::kId;
  info.type = ScalarType::UInt8;
  info.dims = volume.dims;
  info.spacing = volume.spacing;
  info.valueMin = 0, info.valueMax = 255;
  return encodeInput(in, info, params, progress, stats, Volume{}, [&](const CompressedVolume& cv) {
    return psnrRgba(volume, decodeRgba(cv.info, cv.view()));
  });
}

RgbaVolume generateMengerRgba(int level) {
  const Volume m = generateMenger(level);
  RgbaVolume out;
  out.dims = m.dims;
  out.rgba.assign(m.voxelCount(), 0);
  const int n = m.dims.x;
  const std::uint8_t* src = m.as<std::uint8_t>().data();
  auto ramp = [&](int i) {
    return n > 1 ? std::uint32_t((255 * i + (n - 1) / 2) / (n - 1)) : 255u;
  };
  std::size_t i = 0;
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x, ++i)
        if (src[i]) out.rgba[i] = ramp(x) | (ramp(y) << 8) | (ramp(z) << 16) | (255u << 24);
  return out;
}

double psnrRgba(const RgbaVolume& a, const RgbaVolume& b) {
  if (a.dims != b.dims || a.rgba.size() != b.rgba.size())
    throw std::invalid_argument("psnrRgba: volumes differ in size");
  long double se = 0;
  for (std::size_t i = 0; i < a.rgba.size(); ++i)
    for (int c = 0; c < 4; ++c) {
      const double d =
          double((a.rgba[i] >> (8 * c)) & 255u) - double((b.rgba[i] >> (8 * c)) & 255u);
      se += d * d;
    }
  if (se == 0) return std::numeric_limits<double>::infinity();
  const double mse = double(se / (4.0L * (long double)a.rgba.size()));
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

}  // namespace voxwall::codec::svmm
