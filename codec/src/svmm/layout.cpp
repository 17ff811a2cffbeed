// The svmm layout: every section checked against the header before anything reads it, the view
// and pools the raycasters sample, and the decoders. The format is documented in svmm_codec.hpp.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <voxwall/codec/brick_volume.hpp>
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
using kernels::svmmBaseBytes;
using kernels::svmmWordBytes;

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  cacheId_ = mintCacheIds();
  readParams(sections);
  ByteReader data = readData(sections);
  checkSubBlockOffsets(data);
}

void Layout::readParams(const SectionSet& sections) {
  const std::string& src = sections.source;
  ByteReader r(sections.get(kParams, "params"), src, "section 'params'");
  auto fail = [&](const std::string& what) { r.fail(what); };
  format_ = int(r.get<std::uint32_t>());
  flags_ = r.get<std::uint32_t>();
  bias_ = r.get<std::int32_t>();
  quality_ = int(r.get<std::uint32_t>());
  delta_ = r.get<double>();
  peak_ = r.get<double>();
  rootWidth_ = int(r.get<std::uint32_t>());
  const std::uint32_t stepped = r.get<std::uint32_t>();
  const std::uint32_t levels = r.get<std::uint32_t>();
  root_.x = int(r.get<std::uint32_t>());
  root_.y = int(r.get<std::uint32_t>());
  root_.z = int(r.get<std::uint32_t>());
  if (format_ < 1 || format_ > 3) fail("voxel format " + std::to_string(format_));
  if ((format_ == kSvmmDensity16) !=
          (info_.type == ScalarType::UInt16 || info_.type == ScalarType::Int16) ||
      (format_ != kSvmmDensity16 && info_.type != ScalarType::UInt8))
    fail("voxel format " + std::to_string(format_) + " does not match scalar type " +
         std::string(scalarName(info_.type)));
  if (flags_ > 1) fail("flags " + std::to_string(flags_));
  if (bias_ != (info_.type == ScalarType::Int16 ? kInt16Bias : 0))
    fail("bias " + std::to_string(bias_));
  if (quality_ > 100) fail("quality " + std::to_string(quality_));
  if (!(delta_ >= 0 && delta_ <= 2.0) || !(peak_ > 0 && peak_ <= 65535))
    fail("delta or peak out of range");
  if (rootWidth_ < 2) fail("root width " + std::to_string(rootWidth_));
  if (stepped > 1) fail("stepped flag " + std::to_string(stepped));
  stepped_ = stepped == 1;
  if (levels < 1 || levels > std::uint32_t(kernels::kSvmmMaxLevels))
    fail(std::to_string(levels) + " levels (1..16)");
  levels_ = int(levels);
  const int top = levels_ - 1;
  int shift = 0;
  for (int i = 0; i < levels_; ++i) {
    const int w = int(r.get<std::uint32_t>());
    const int s = int(r.get<std::uint32_t>());
    widths_.push_back(w);
    shifts_.push_back(s);
    blocks_.push_back(r.get<std::uint64_t>());
    offsets_.push_back(r.get<std::uint64_t>());
    bytes_.push_back(r.get<std::uint64_t>());
    const std::string lv = "level " + std::to_string(i) + ": ";
    if (i < top ? (w < 2 || w > 256 || !std::has_single_bit(unsigned(w))) : w != 0)
      fail(lv + "block width " + std::to_string(w));
    if (s != shift)
      fail(lv + "shift " + std::to_string(s) + " (expected " + std::to_string(shift) + ")");
    if (i < top) shift += std::countr_zero(unsigned(w));
    if (shift > 30) fail(lv + "mipmap factor over 2^30");
  }
  psnr_ = r.get<double>();
  const glm::ivec3 topLogical = logicalDims(info_.dims, shifts_[std::size_t(top)]);
  const glm::ivec3 wantRoot = levels_ == 1 ? info_.dims : evenUp(topLogical);
  if (root_ != wantRoot)
    fail("root grid " + std::to_string(root_.x) + "x" + std::to_string(root_.y) + "x" +
         std::to_string(root_.z) + " does not fit the volume");
  if (blocks_[std::size_t(top)] != 1) fail("the root level must have one block");
  // Volume coordinates of every voxel of every level (and one past) must fit in an int.
  if ((std::int64_t(maxOf(root_)) << shifts_[std::size_t(top)]) > std::int64_t(1) << 30)
    fail("mipmap factor too large for the volume");
}

// The data section: every level's bytes inside it, in order, filled by its blocks.
ByteReader Layout::readData(const SectionSet& sections) {
  const std::string& src = sections.source;
  data_ = sections.get(kData, "data");
  ByteReader dr(data_, src, "section 'data'");
  auto dfail = [&](const std::string& what) { dr.fail(what); };
  const int top = levels_ - 1;
  std::uint64_t end = 0;
  for (int L = top; L >= 0; --L) {
    const std::string lv = "level " + std::to_string(L) + ": ";
    const std::uint64_t blockBytes = blockBytesOf(L);
    const std::uint64_t off = offsets_[std::size_t(L)], len = bytes_[std::size_t(L)];
    if (off % 8 || off < end || off > data_.size() || len > data_.size() - off)
      dfail(lv + "bytes [" + std::to_string(off) + ", +" + std::to_string(len) +
            ") outside the section or overlapping");
    if (blocks_[std::size_t(L)] > data_.size() || blocks_[std::size_t(L)] * blockBytes != len)
      dfail(lv + std::to_string(blocks_[std::size_t(L)]) + " blocks do not fill " +
            std::to_string(len) + " bytes");
    end = off + len;
  }
  return dr;
}

void Layout::checkSubBlockOffsets(const ByteReader& dr) const {
  auto dfail = [&](const std::string& what) { dr.fail(what); };
  const int top = levels_ - 1;
  // Every sub-block's offset must be the running count of blocks below: then every child index
  // a view computes is inside its level.
  const kernels::SvmmView v = view();
  for (int L = top; L >= 1; --L) {
    const glm::ivec3 size = L == top ? root_ : glm::ivec3(widths_[std::size_t(L)]);
    const std::size_t sy = std::size_t(size.x), sz = sy * std::size_t(size.y);
    std::uint64_t counter = 0;
    for (std::uint64_t b = 0; b < blocks_[std::size_t(L)]; ++b) {
      const std::uint8_t* block = v.level[L].data + b * v.level[L].blockBytes;
      for (int bz = 0; bz < size.z; bz += 2)
        for (int by = 0; by < size.y; by += 2)
          for (int bx = 0; bx < size.x; bx += 2) {
            const std::size_t s0 = std::size_t(bz) * sz + std::size_t(by) * sy + std::size_t(bx);
            std::uint32_t offset = 0, count = 0;
            for (int j = 0; j < 8; ++j) {
              const std::uint32_t wj =
                  v.word(block, s0 + std::size_t(j & 1) + (j & 2 ? sy : 0) + (j & 4 ? sz : 0));
              offset |= (wj & 15u) << (4 * j);
              count += !(wj & kSvmmTerminal);
            }
            if (count && offset != counter)
              dfail("level " + std::to_string(L) + ", block " + std::to_string(b) +
                    ": sub-block offset " + std::to_string(offset) + " (expected " +
                    std::to_string(counter) + ")");
            counter += count;
          }
    }
    if (counter != blocks_[std::size_t(L - 1)])
      dfail("level " + std::to_string(L) + " points to " + std::to_string(counter) +
            " blocks, level " + std::to_string(L - 1) + " has " +
            std::to_string(blocks_[std::size_t(L - 1)]));
  }
}

kernels::SvmmView Layout::view(const std::byte* base) const {
  kernels::SvmmView v;
  const auto* b = reinterpret_cast<const std::uint8_t*>(base ? base : data_.data());
  v.levels = levels_;
  v.format = format_;
  v.blockCompressed = (flags_ & kBlockCompressed) && levels_ > 1;
  v.bias = bias_;
  v.dimX = info_.dims.x, v.dimY = info_.dims.y, v.dimZ = info_.dims.z;
  v.maxX = float(v.dimX - 1), v.maxY = float(v.dimY - 1), v.maxZ = float(v.dimZ - 1);
  v.cacheId = cacheId_;
  v.rootX = root_.x, v.rootY = root_.y, v.rootZ = root_.z;
  const int top = levels_ - 1;
  for (int L = 0; L < levels_; ++L) {
    auto& l = v.level[L];
    l.data = b + offsets_[std::size_t(L)];
    l.shift = shifts_[std::size_t(L)];
    l.widthLog2 = L < top ? std::countr_zero(unsigned(widths_[std::size_t(L)])) : 0;
    l.blockBytes = blockBytesOf(L);
  }
  return v;
}

std::uint64_t Layout::blockBytesOf(int L) const {
  const std::uint64_t ws = std::uint64_t(svmmWordBytes(format_)),
                      bs = std::uint64_t(svmmBaseBytes(format_));
  if (L == levels_ - 1) return count3(root_) * (levels_ == 1 ? bs : ws);
  const std::uint64_t w = std::uint64_t(widths_[std::size_t(L)]);
  if (L > 0) return w * w * w * ws;
  return (flags_ & kBlockCompressed) ? (w / 2) * (w / 2) * (w / 2) * (1 + bs) : w * w * w * bs;
}

bool Layout::poolable(int L) const {
  return L >= 0 && L < levels_ - 1 && blocks_[std::size_t(L)] > 0 &&
         !(L == 0 && (flags_ & kBlockCompressed));
}

kernels::SvmmPoolShape Layout::poolShape(int L) const {
  return kernels::svmmPoolShape(blocks_[std::size_t(L)]);
}

int Layout::elementBytes(int L) const {
  return L == 0 ? svmmBaseBytes(format_) : svmmWordBytes(format_);
}

std::vector<std::uint8_t> Layout::poolBytes(int L) const {
  if (!poolable(L)) throw std::invalid_argument("level " + std::to_string(L) + " has no pool");
  const auto shape = poolShape(L);
  const int wl = std::countr_zero(unsigned(widths_[std::size_t(L)]));
  const std::uint64_t w = std::uint64_t(1) << wl;
  const std::uint64_t sx = std::uint64_t(1) << (shape.uLog2 + wl),
                      sy = std::uint64_t(1) << (shape.vLog2 + wl), sz = shape.w << wl;
  const std::uint64_t bytes = std::uint64_t(elementBytes(L));
  std::vector<std::uint8_t> out(sx * sy * sz * bytes, 0);
  const auto v = view();
  const std::uint8_t* src = v.level[L].data;
  for (std::uint64_t b = 0; b < blocks_[std::size_t(L)]; ++b) {
    std::uint64_t u, vv, ww;
    kernels::svmmPoolBlock(b, shape.uLog2, shape.vLog2, u, vv, ww);
    for (std::uint64_t z = 0; z < w; ++z)
      for (std::uint64_t y = 0; y < w; ++y) {
        const std::uint64_t dst = (((ww * w + z) * sy + vv * w + y) * sx + u * w) * bytes;
        std::memcpy(out.data() + dst, src + b * v.level[L].blockBytes + ((z * w + y) * w) * bytes,
                    w * bytes);
      }
  }
  return out;
}

RangeGrid Layout::rangeGrid() const {
  constexpr int kCell = 4;  // as the raw codec's default
  const kernels::SvmmView v = view();
  // Where the base level is of blocks that the view reads whole, on every core, a row of them at
  // a time (one walk down the mip-map a block): the walk over the leaves below widens up to 27
  // cells a voxel on one core (a job of one small frame of a 119 Mvox MRI took 2.7 s with it,
  // 0.9 s without).
  if (const int w = v.baseBlockSide(); w > 0)
    return blockRangeGrid<std::uint32_t>(
        info_.dims, info_.type, kCell, w, 16u << 20,
        [&](int bx, int by, int bz, std::uint32_t* out) { v.baseBlock(bx, by, bz, out); },
        [&](std::uint32_t x) { return v.scalar(x); });
  RangeGrid g(kCell, (info_.dims + kCell - 1) / kCell, info_.type);
  const glm::ivec3 last = info_.dims - 1;
  // Each value goes to every cell within one voxel of where it is (the dilation the raycaster
  // relies on: a trilinear sample whose lower corner is in a cell reads up to one voxel past it).
  auto add = [&](glm::ivec3 a, glm::ivec3 b, float s) {
    a = glm::max(a - 1, glm::ivec3(0)) / kCell;
    b = glm::min(b + 1, last) / kCell;
    for (int cz = a.z; cz <= b.z; ++cz)
      for (int cy = a.y; cy <= b.y; ++cy)
        for (int cx = a.x; cx <= b.x; ++cx) g.widen(g.cellIndex(cx, cy, cz), s);
  };
  forEachLeaf(
      [&](int, int x0, int y0, int z0, int size, std::uint32_t value) {
        const glm::ivec3 a(x0, y0, z0);
        const glm::ivec3 b = glm::min(a + size - 1, last);
        if (b.x < a.x || b.y < a.y || b.z < a.z) return;
        add(a, b, v.scalar(value));
      },
      [&](int x, int y, int z, std::uint32_t value) {
        const glm::ivec3 p(x, y, z);
        add(p, p, v.scalar(value));
      });
  return g;
}

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  const Layout layout(info, sections);
  if (layout.format() == kSvmmRgba32)
    throw FormatError(sections.source, "an RGBA svmm volume has no scalar decode (use decodeRgba)");
  Volume out = Volume::allocate(info.dims, info.type, info.spacing);
  const kernels::SvmmView v = layout.view();
  dispatchScalar(info.type, [&](auto t) {
    using T = decltype(t);
    T* dst = out.as<T>().data();
    auto at = [&](int x, int y, int z) {
      return (std::size_t(z) * std::size_t(info.dims.y) + std::size_t(y)) *
                 std::size_t(info.dims.x) +
             std::size_t(x);
    };
    layout.forEachLeaf(
        [&](int, int x0, int y0, int z0, int size, std::uint32_t value) {
          const T s = T(int(value) - v.bias);
          const glm::ivec3 b = glm::min(glm::ivec3(x0, y0, z0) + size, info.dims);
          for (int z = z0; z < b.z; ++z)
            for (int y = y0; y < b.y; ++y)
              for (int x = x0; x < b.x; ++x) dst[at(x, y, z)] = s;
        },
        [&](int x, int y, int z, std::uint32_t value) {
          dst[at(x, y, z)] = T(int(value) - v.bias);
        });
  });
  out.computeRange();
  return out;
}

RgbaVolume decodeRgba(const VolumeInfo& info, const SectionSet& sections) {
  const Layout layout(info, sections);
  if (layout.format() != kSvmmRgba32) throw FormatError(sections.source, "not an RGBA svmm volume");
  RgbaVolume out;
  out.dims = info.dims;
  out.spacing = info.spacing;
  out.rgba.assign(info.voxelCount(), 0);
  auto at = [&](int x, int y, int z) {
    return (std::size_t(z) * std::size_t(info.dims.y) + std::size_t(y)) * std::size_t(info.dims.x) +
           std::size_t(x);
  };
  layout.forEachLeaf(
      [&](int, int x0, int y0, int z0, int size, std::uint32_t value) {
        const glm::ivec3 b = glm::min(glm::ivec3(x0, y0, z0) + size, info.dims);
        for (int z = z0; z < b.z; ++z)
          for (int y = y0; y < b.y; ++y)
            for (int x = x0; x < b.x; ++x) out.rgba[at(x, y, z)] = value;
      },
      [&](int x, int y, int z, std::uint32_t value) { out.rgba[at(x, y, z)] = value; });
  return out;
}
}  // namespace voxwall::codec::svmm
