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
  // Level 0 of a scalar volume is read from the volume's own voxels through `read` (no copy of
  // 4 bytes per voxel); `value` is then empty.
  const void* base = nullptr;
  std::uint32_t (*read)(const void*, std::size_t) = nullptr;
  std::uint32_t get(std::size_t i) const { return base ? read(base, i) : value[i]; }
  std::size_t at(int x, int y, int z) const {
    return (std::size_t(z) * std::size_t(padded.y) + std::size_t(y)) * std::size_t(padded.x) +
           std::size_t(x);
  }
  bool inside(glm::ivec3 g) const { return g.x < padded.x && g.y < padded.y && g.z < padded.z; }
  std::uint32_t valueAt(glm::ivec3 g) const { return inside(g) ? get(at(g.x, g.y, g.z)) : 0u; }
  bool terminalAt(glm::ivec3 g) const {
    return !inside(g) || terminal.empty() || terminal[at(g.x, g.y, g.z)];
  }
};

// Level i + 1 from level i (blocks of w^3).
Grid buildLevel(const Grid& fine, int w, int format, double threshold2, int threads,
                Progress& progress) {
  Grid g;
  g.logical = (fine.logical + w - 1) / w;
  g.padded = evenUp(g.logical);
  g.value.assign(count3(g.padded), 0);
  g.terminal.assign(count3(g.padded), 1);
  const int channels = channelsOf(format);
  parallelFor(std::size_t(g.logical.z), threads, [&](std::size_t zi) {
    const int z = int(zi);
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
  return g;
}

void putValue(std::vector<std::byte>& out, std::uint32_t v, int bytes) {
  for (int b = 0; b < bytes; ++b) out.push_back(std::byte((v >> (8 * b)) & 255u));
}

template <class T, int Bias>
std::uint32_t readBiased(const void* voxels, std::size_t i) {
  return std::uint32_t(int(static_cast<const T*>(voxels)[i]) + Bias);
}

struct Input {
  glm::ivec3 dims;
  int format;
  int bias;
  double peak;
  std::vector<std::uint32_t> values;  // x fastest (RGBA)
  const void* base = nullptr;         // or the scalar voxels, read through `read`
  std::uint32_t (*read)(const void*, std::size_t) = nullptr;
};

// The mip-map: the grid of every level (0 the input), the block widths and shifts, and, once
// written, each level's block count and place in the data section.
struct Levels {
  std::vector<Grid> grids;
  std::vector<int> widths, shifts{0};
  int n = 1;
  glm::ivec3 rootGrid{};
  std::vector<std::uint64_t> blocks, offsets, lengths;
};

// Level after level, until one fits in the root width (the top).
Levels buildLevels(Input& in, const Params& p, double threshold2, Progress& progress) {
  Levels lv;
  lv.grids.resize(1);
  Grid& base = lv.grids[0];
  base.logical = in.dims;
  base.padded = in.dims;
  base.value = std::move(in.values);
  base.base = in.base, base.read = in.read;
  while (maxOf(lv.grids.back().logical) > p.rootWidth) {
    if (int(lv.grids.size()) == kernels::kSvmmMaxLevels)
      throw std::invalid_argument("more than 16 mip levels: raise the root width");
    const int i = int(lv.grids.size()) - 1;
    const int w = p.stepped ? std::min(2 << i, 256) : p.blockWidth;
    const glm::ivec3 next = (lv.grids.back().logical + w - 1) / w;
    progress.begin("svmm: level " + std::to_string(i + 1), std::uint64_t(next.z));
    lv.grids.push_back(buildLevel(lv.grids.back(), w, in.format, threshold2, p.threads, progress));
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

// One block of level L at `origin` (level-L voxels) of `size` voxels, as words: value, terminal
// bit and the offset nibble of its children's first block in level L - 1, whose origins are
// appended to `next`.
void writeBlock(const Levels& lv, int L, glm::ivec3 origin, glm::ivec3 size, int format,
                std::vector<glm::ivec3>& next, std::vector<std::uint32_t>& words) {
  const Grid& G = lv.grids[std::size_t(L)];
  const int childW = lv.widths[std::size_t(L - 1)];
  for (int bz = 0; bz < size.z; bz += 2)
    for (int by = 0; by < size.y; by += 2)
      for (int bx = 0; bx < size.x; bx += 2) {
        const std::size_t first = next.size();
        bool term[8];
        for (int j = 0; j < 8; ++j) {
          const glm::ivec3 g = origin + glm::ivec3(bx + (j & 1), by + (j >> 1 & 1), bz + (j >> 2));
          term[j] = G.terminalAt(g);
          if (!term[j]) next.push_back(g * childW);
        }
        if (next.size() > std::numeric_limits<std::uint32_t>::max())
          throw std::invalid_argument("a level has more than 2^32 blocks");
        const std::uint32_t off = next.size() > first ? std::uint32_t(first) : 0u;
        for (int j = 0; j < 8; ++j) {
          const glm::ivec3 l(bx + (j & 1), by + (j >> 1 & 1), bz + (j >> 2));
          words[(std::size_t(l.z) * std::size_t(size.y) + std::size_t(l.y)) * std::size_t(size.x) +
                std::size_t(l.x)] =
              packWord(format, G.valueAt(origin + l), term[j], (off >> (4 * j)) & 15u);
        }
      }
}

// Levels top .. 1, in tree order, into the data section (each 8-byte aligned); returns the
// origins of the base level's blocks.
std::vector<glm::ivec3> writeUpperLevels(Levels& lv, int format, std::vector<std::byte>& data,
                                         Progress& progress) {
  const int top = lv.n - 1, ws = svmmWordBytes(format);
  std::vector<std::vector<std::byte>> out(static_cast<std::size_t>(lv.n));
  std::vector<glm::ivec3> cur{glm::ivec3(0)};  // block origins of level L, in level-L voxels
  for (int L = top; L >= 1; --L) {
    const glm::ivec3 size = L == top ? lv.rootGrid : glm::ivec3(lv.widths[std::size_t(L)]);
    std::vector<glm::ivec3> next;
    std::vector<std::uint32_t> words(count3(size));
    auto& o = out[std::size_t(L)];
    o.reserve(cur.size() * words.size() * std::size_t(ws));
    for (const glm::ivec3 origin : cur) {
      writeBlock(lv, L, origin, size, format, next, words);
      for (const std::uint32_t w : words) putValue(o, w, ws);
    }
    lv.blocks[std::size_t(L - 1)] = next.size();
    cur = std::move(next);
    progress.advance();
  }
  for (int L = top; L >= 1; --L) {
    while (data.size() % 8) data.push_back(std::byte{0});
    lv.offsets[std::size_t(L)] = data.size();
    lv.lengths[std::size_t(L)] = out[std::size_t(L)].size();
    data.insert(data.end(), out[std::size_t(L)].begin(), out[std::size_t(L)].end());
    std::vector<std::byte>().swap(out[std::size_t(L)]);
  }
  return cur;
}

// A base block's 2^3 group as stored with --base-compression: a byte of occupancy and the mean of
// the occupied voxels.
void writeCompressedGroup(const Grid& G, glm::ivec3 corner, int format, std::vector<std::byte>& o) {
  const int channels = channelsOf(format);
  std::uint32_t bitmap = 0;
  std::uint64_t sum[4] = {0, 0, 0, 0}, cnt = 0;
  for (int j = 0; j < 8; ++j) {
    const glm::ivec3 q = corner + glm::ivec3(j & 1, j >> 1 & 1, j >> 2);
    const bool in = q.x < G.logical.x && q.y < G.logical.y && q.z < G.logical.z;
    const std::uint32_t v = in ? G.get(G.at(q.x, q.y, q.z)) : 0u;
    const bool occupied = format == kSvmmRgba32 ? (v >> 24) != 0 : v != 0;
    if (!occupied) continue;
    bitmap |= 1u << j;
    ++cnt;
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
  o.push_back(std::byte(bitmap));
  putValue(o, mean, svmmBaseBytes(format));
}

// The base level, written straight into the data section (it is most of the file: a second copy
// of it would double the encoder's peak): the whole grid without levels, else its blocks.
void writeBaseLevel(const Levels& lv, const std::vector<glm::ivec3>& origins, int format,
                    bool compressBase, std::vector<std::byte>& o) {
  const Grid& G = lv.grids[0];
  const int bs = svmmBaseBytes(format);
  if (lv.n == 1) {
    const std::size_t voxels = count3(G.padded);
    o.reserve(o.size() + voxels * std::size_t(bs) + 8);  // + the 8 zero bytes at the end
    for (std::size_t i = 0; i < voxels; ++i) putValue(o, G.get(i), bs);
    return;
  }
  const int w = lv.widths[0];
  // The most the base level takes (uncompressed blocks), and the 8 zero bytes at the end: a
  // reallocation past it would copy the whole section into twice its size.
  o.reserve(o.size() + origins.size() * std::size_t(w * w * w) * std::size_t(bs) + 8);
  for (const glm::ivec3 origin : origins) {
    if (compressBase) {
      for (int gz = 0; gz < w; gz += 2)
        for (int gy = 0; gy < w; gy += 2)
          for (int gx = 0; gx < w; gx += 2)
            writeCompressedGroup(G, origin + glm::ivec3(gx, gy, gz), format, o);
      continue;
    }
    for (int z = 0; z < w; ++z)
      for (int y = 0; y < w; ++y)
        for (int x = 0; x < w; ++x) {
          const glm::ivec3 q = origin + glm::ivec3(x, y, z);
          const bool in = q.x < G.logical.x && q.y < G.logical.y && q.z < G.logical.z;
          putValue(o, in ? G.get(G.at(q.x, q.y, q.z)) : 0u, bs);
        }
  }
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

CompressedVolume encodeInput(Input in, VolumeInfo info, const Params& p, Progress& progress,
                             EncodeStats* stats,
                             const std::function<double(const CompressedVolume&)>& measure) {
  if (p.rootWidth < 2) throw std::invalid_argument("root width must be at least 2");
  if (!p.stepped &&
      (p.blockWidth < 2 || p.blockWidth > 64 || !std::has_single_bit(unsigned(p.blockWidth))))
    throw std::invalid_argument("block width must be a power of two in 2..64");
  const double delta = deltaForQuality(p.quality, channelsOf(in.format));
  const double thr = delta * in.peak;
  Levels lv = buildLevels(in, p, thr * thr, progress);
  const bool compressBase = p.baseCompression && lv.n > 1;

  progress.begin("svmm: writing blocks", std::uint64_t(lv.n));
  std::vector<std::byte> data;
  const std::vector<glm::ivec3> baseBlocks = writeUpperLevels(lv, in.format, data, progress);
  while (data.size() % 8) data.push_back(std::byte{0});
  lv.offsets[0] = data.size();
  writeBaseLevel(lv, baseBlocks, in.format, compressBase, data);
  progress.advance();
  progress.end();
  lv.lengths[0] = data.size() - lv.offsets[0];
  for (int i = 0; i < 8; ++i) data.push_back(std::byte{0});

  CompressedVolume cv;
  cv.info = info;
  cv.sections.emplace_back(kParams, paramsSection(in, p, lv, compressBase, delta, 0.0));
  cv.sections.emplace_back(kData, std::move(data));
  progress.begin("svmm: measuring PSNR", 1);
  const double psnrValue = measure(cv);
  progress.advance();
  progress.end();
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

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress,
                        EncodeStats* stats) {
  Input in;
  in.dims = volume.dims;
  in.bias = 0;
  switch (volume.type) {
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
                                  std::string(scalarName(volume.type)));
  }
  in.peak = volume.valueMax - volume.valueMin;
  if (!(in.peak > 0)) in.peak = 1;
  in.base = volume.data.data();
  in.read = volume.type == ScalarType::UInt8    ? &readBiased<std::uint8_t, 0>
            : volume.type == ScalarType::UInt16 ? &readBiased<std::uint16_t, 0>
                                                : &readBiased<std::int16_t, kInt16Bias>;
  const VolumeInfo info = volumeInfo(volume, SvmmCodecEntry::kId);
  // PSNR from the stored tree's leaves against the volume, leaf by leaf (no decoded copy).
  return encodeInput(std::move(in), info, params, progress, stats, [&](const CompressedVolume& cv) {
    const Layout layout(cv.info, cv.view());
    const int bias = layout.view().bias;
    PsnrSum sum(volume);
    dispatchScalar(volume.type, [&](auto t) {
      using T = decltype(t);
      const T* src = volume.as<T>().data();
      layout.forEachLeaf(
          [&](int, int x0, int y0, int z0, int size, std::uint32_t value) {
            const double v = double(T(int(value) - bias));
            const glm::ivec3 b = glm::min(glm::ivec3(x0, y0, z0) + size, volume.dims);
            if (b.x <= x0) return;
            for (int z = z0; z < b.z; ++z)
              for (int y = y0; y < b.y; ++y)
                sum.addConstant(src + volume.index(x0, y, z), v, std::size_t(b.x - x0));
          },
          [&](int x, int y, int z, std::uint32_t value) {
            const double v = double(T(int(value) - bias));
            sum.addConstant(src + volume.index(x, y, z), v, 1);
          });
    });
    return sum.psnr();
  });
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
  in.values = volume.rgba;
  VolumeInfo info;
  info.codec = SvmmCodecEntry::kId;
  info.type = ScalarType::UInt8;
  info.dims = volume.dims;
  info.spacing = volume.spacing;
  info.valueMin = 0, info.valueMax = 255;
  return encodeInput(std::move(in), info, params, progress, stats, [&](const CompressedVolume& cv) {
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
