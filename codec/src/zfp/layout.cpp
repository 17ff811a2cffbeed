// The zfp codec's reader: each brick's stream through libzfp, the sections' checks, the host view
// and the full decode.
#include <zfp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/core/bytes.hpp>

#include "format.hpp"

namespace voxwall::codec::zfp {

std::string_view modeName(Mode mode) {
  switch (mode) {
    case Mode::Accuracy:
      return "fixed accuracy";
    case Mode::Precision:
      return "fixed precision";
    case Mode::Rate:
      return "fixed rate";
    case Mode::Reversible:
      return "reversible (lossless)";
  }
  return "unknown";
}

glm::ivec3 brickGrid(glm::ivec3 dims) { return (dims + kBrick - 1) / kBrick; }

BrickShape brickShape(glm::ivec3 dims, std::uint64_t brick) {
  const glm::ivec3 g = brickGrid(dims);
  const int bx = int(brick % std::uint64_t(g.x));
  const int by = int(brick / std::uint64_t(g.x) % std::uint64_t(g.y));
  const int bz = int(brick / (std::uint64_t(g.x) * std::uint64_t(g.y)));
  BrickShape s;
  s.nx = std::min(kBrick, dims.x - bx * kBrick);
  s.ny = std::min(kBrick, dims.y - by * kBrick);
  s.nz = std::min(kBrick, dims.z - bz * kBrick);
  return s;
}

namespace {

// A zfp_stream (and its bit stream, when one is given), closed on scope exit.
struct Stream {
  zfp_stream* zfp = zfp_stream_open(nullptr);
  bitstream* bits = nullptr;
  Stream() = default;
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  ~Stream() {
    if (bits) stream_close(bits);
    zfp_stream_close(zfp);
  }
  bool set(const kernels::ZfpStreamParams& p) {
    return zfp_stream_set_params(zfp, p.minbits, p.maxbits, p.maxprec, p.minexp);
  }
  void attach(void* buffer, std::size_t bytes) {
    bits = stream_open(buffer, bytes);
    zfp_stream_set_bit_stream(zfp, bits);
    zfp_stream_rewind(zfp);
  }
};

// The brick's voxels as a zfp field: x fastest with the brick's strides.
struct Field {
  zfp_field* field;
  Field(float* data, const BrickShape& s)
      : field(zfp_field_3d(data, zfp_type_float, std::size_t(s.nx), std::size_t(s.ny),
                           std::size_t(s.nz))) {
    zfp_field_set_stride_3d(field, 1, kBrick, kBrick * kBrick);
  }
  Field(const Field&) = delete;
  Field& operator=(const Field&) = delete;
  ~Field() { zfp_field_free(field); }
};

}  // namespace

kernels::ZfpStreamParams streamParams(Mode mode, double setting) {
  Stream s;
  switch (mode) {
    case Mode::Accuracy:
      zfp_stream_set_accuracy(s.zfp, setting);
      break;
    case Mode::Precision:
      zfp_stream_set_precision(s.zfp, unsigned(setting));
      break;
    case Mode::Rate:
      zfp_stream_set_rate(s.zfp, setting, zfp_type_float, 3, zfp_false);
      break;
    case Mode::Reversible:
      zfp_stream_set_reversible(s.zfp);
      break;
  }
  kernels::ZfpStreamParams p;
  unsigned minbits = 0, maxbits = 0, maxprec = 0;
  int minexp = 0;
  zfp_stream_params(s.zfp, &minbits, &maxbits, &maxprec, &minexp);
  p.minbits = minbits, p.maxbits = maxbits, p.maxprec = maxprec, p.minexp = minexp;
  if (modeOf(p) != mode)
    throw std::invalid_argument("zfp does not take " + std::string(modeName(mode)) + " " +
                                std::to_string(setting));
  return p;
}

Mode modeOf(const kernels::ZfpStreamParams& p) {
  if (p.maxbits == 0 || p.maxbits > ZFP_MAX_BITS || p.minbits > p.maxbits || p.maxprec == 0 ||
      p.maxprec > ZFP_MAX_PREC)
    return Mode{0};
  Stream s;
  if (!s.set(p)) return Mode{0};
  switch (zfp_stream_compression_mode(s.zfp)) {
    case zfp_mode_fixed_accuracy:
      return Mode::Accuracy;
    case zfp_mode_fixed_precision:
      return Mode::Precision;
    case zfp_mode_fixed_rate:
      return Mode::Rate;
    case zfp_mode_reversible:
      return Mode::Reversible;
    default:
      return Mode{0};
  }
}

std::size_t maxStreamBytes(const kernels::ZfpStreamParams& p, const BrickShape& shape) {
  const std::size_t bitsPerBlock = std::max(p.maxbits, p.minbits);
  return (std::size_t(shape.blocks()) * bitsPerBlock + 63) / 64 * 8 + 16;
}

std::size_t compressBrick(const kernels::ZfpStreamParams& params, const float* in,
                          const BrickShape& shape, std::vector<std::uint8_t>& out) {
  Stream s;
  s.set(params);
  Field f(const_cast<float*>(in), shape);
  const std::size_t capacity = zfp_stream_maximum_size(s.zfp, f.field);
  const std::size_t at = out.size();
  out.resize(at + capacity + 8);
  s.attach(out.data() + at, capacity + 8);
  const std::size_t bytes = zfp_compress(s.zfp, f.field);
  if (bytes == 0) throw std::runtime_error("zfp could not compress a brick");
  out.resize(at + (bytes + 7) / 8 * 8);
  return out.size() - at;
}

void decompressBrick(const kernels::ZfpStreamParams& params, const std::uint8_t* data,
                     std::size_t bytes, const BrickShape& shape, float* out) {
  // zfp's bit reader trusts the stream: it reads what each block's bit budget allows, past the
  // brick's end when the bytes are corrupt. It reads a copy padded with zeros to that bound.
  thread_local std::vector<std::uint8_t> scratch;
  const std::size_t bound = maxStreamBytes(params, shape);
  if (scratch.size() < bound + bytes) scratch.resize(bound + bytes);
  std::memcpy(scratch.data(), data, bytes);
  std::memset(scratch.data() + bytes, 0, bound);
  Stream s;
  s.set(params);
  s.attach(scratch.data(), bound + bytes);
  Field f(out, shape);
  zfp_decompress(s.zfp, f.field);
}

// ---- the host view's decoder ------------------------------------------------------------

namespace {
std::uint64_t indexEntry(const std::uint8_t* index, std::uint64_t i) {
  std::uint64_t e;
  std::memcpy(&e, index + 8 * i, 8);
  return e;
}
}  // namespace

}  // namespace voxwall::codec::zfp

namespace voxwall::codec::kernels {

void zfpDecodeBrick(const ZfpDecoder& d, std::uint64_t brick, float* out) {
  using namespace voxwall::codec::zfp;
  const std::uint64_t e0 = indexEntry(d.index, brick), e1 = indexEntry(d.index, brick + 1);
  const std::uint64_t at = e0 & ~kStoredBit, bytes = (e1 & ~kStoredBit) - at;
  const BrickShape s = brickShape({d.dimX, d.dimY, d.dimZ}, brick);
  const ScalarType type = ScalarType(d.type);
  std::fill(out, out + kBrickVoxels, 0.0f);
  const std::uint8_t* data = d.stream + at;
  if (e0 & kStoredBit) {
    dispatchScalar(type, [&](auto t) {
      using T = decltype(t);
      std::size_t i = 0;
      for (int z = 0; z < s.nz; ++z)
        for (int y = 0; y < s.ny; ++y)
          for (int x = 0; x < s.nx; ++x, ++i) {
            T v;
            std::memcpy(&v, data + i * sizeof(T), sizeof(T));
            out[x + kBrick * (y + kBrick * z)] = float(v);
          }
    });
  } else {
    decompressBrick(d.zfp, data, std::size_t(bytes), s, out);
  }
  const bool integer = type != ScalarType::Float32;
  for (int z = 0; z < s.nz; ++z)
    for (int y = 0; y < s.ny; ++y) {
      float* row = out + kBrick * (y + kBrick * z);
      for (int x = 0; x < s.nx; ++x) row[x] = finish(row[x], d.lo, d.hi, integer);
    }
}

}  // namespace voxwall::codec::kernels

namespace voxwall::codec::zfp {

// ---- the sections ---------------------------------------------------------------------------

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  static std::atomic<std::uint64_t> nextCacheId{1};
  cacheId_ = nextCacheId.fetch_add(1);
  const std::string& src = sections.source;
  params_ = sections.get(kParams, "params");
  ByteReader r(params_, src, "section 'params'");
  const auto mode = r.get<std::uint32_t>();
  zfp_.minbits = r.get<std::uint32_t>(), zfp_.maxbits = r.get<std::uint32_t>();
  zfp_.maxprec = r.get<std::uint32_t>(), zfp_.minexp = r.get<std::int32_t>();
  const auto reserved = r.get<std::uint32_t>();
  setting_ = r.get<double>(), psnr_ = r.get<double>(), maxError_ = r.get<double>();
  storedBricks_ = r.get<std::uint64_t>();
  lo_ = r.get<double>(), hi_ = r.get<double>();
  auto fail = [&](const std::string& what) { r.fail(what); };
  if (params_.size() != kParamsBytes)
    fail(std::to_string(params_.size()) + " bytes, not " + std::to_string(kParamsBytes));
  if (mode < 1 || mode > 4) fail("mode " + std::to_string(mode) + " (1..4)");
  mode_ = Mode(mode);
  if (modeOf(zfp_) != mode_)
    fail("zfp parameters (" + std::to_string(zfp_.minbits) + ", " + std::to_string(zfp_.maxbits) +
         ", " + std::to_string(zfp_.maxprec) + ", " + std::to_string(zfp_.minexp) + ") are not " +
         std::string(modeName(mode_)));
  if (reserved != 0) fail("the reserved field is not 0");
  if (!(lo_ <= hi_) || !std::isfinite(lo_) || !std::isfinite(hi_) ||
      std::abs(lo_) > std::numeric_limits<float>::max() ||
      std::abs(hi_) > std::numeric_limits<float>::max())
    fail("value range " + std::to_string(lo_) + ".." + std::to_string(hi_) + " is not finite");
  const glm::ivec3 g = brickGrid(info.dims);
  bricks_ = std::uint64_t(g.x) * std::uint64_t(g.y) * std::uint64_t(g.z);
  if (storedBricks_ > bricks_) fail("more stored bricks than bricks");

  index_ = sections.get(kIndex, "index");
  stream_ = sections.get(kStream, "stream");
  ByteReader ir(index_, src, "section 'index'");
  auto ifail = [&](const std::string& what) { ir.fail(what); };
  if (index_.size() != (bricks_ + 1) * 8)
    ifail(std::to_string(index_.size()) + " bytes for " + std::to_string(bricks_) + " bricks");
  const auto* index = reinterpret_cast<const std::uint8_t*>(index_.data());
  std::uint64_t stored = 0;
  for (std::uint64_t i = 0; i < bricks_; ++i) {
    const std::uint64_t e0 = indexEntry(index, i), e1 = indexEntry(index, i + 1);
    const std::uint64_t at = e0 & ~kStoredBit, end = e1 & ~kStoredBit;
    const std::string brick = "brick " + std::to_string(i);
    if (i == 0 && at != 0) ifail("the first brick does not start at 0");
    if (at % 8) ifail(brick + " starts at " + std::to_string(at) + ", not a multiple of 8");
    if (end < at || end > stream_.size())
      ifail(brick + " ends at " + std::to_string(end) + ", outside " + std::to_string(at) + ".." +
            std::to_string(stream_.size()));
    const BrickShape s = brickShape(info.dims, i);
    if (e0 & kStoredBit) {
      ++stored;
      if (end - at != storedBytes(info.type, s))
        ifail(brick + " is stored in " + std::to_string(end - at) + " bytes, not " +
              std::to_string(storedBytes(info.type, s)));
    } else if (end - at > maxStreamBytes(zfp_, s)) {
      ifail(brick + "'s stream of " + std::to_string(end - at) +
            " bytes is longer than zfp writes");
    }
  }
  if ((indexEntry(index, bricks_) & ~kStoredBit) != stream_.size() ||
      (indexEntry(index, bricks_) & kStoredBit))
    ifail("the last entry is not the stream's length " + std::to_string(stream_.size()));
  if (stored != storedBricks_)
    fail(std::to_string(stored) + " stored bricks in the index, the header says " +
         std::to_string(storedBricks_));
}

kernels::ZfpView Layout::view() const {
  kernels::ZfpView v;
  kernels::ZfpDecoder& d = v.decoder;
  d.index = reinterpret_cast<const std::uint8_t*>(index_.data());
  d.stream = reinterpret_cast<const std::uint8_t*>(stream_.data());
  const glm::ivec3 g = brickGrid(info_.dims);
  d.bricksX = g.x, d.bricksY = g.y;
  d.dimX = info_.dims.x, d.dimY = info_.dims.y, d.dimZ = info_.dims.z;
  d.type = std::uint32_t(info_.type);
  d.zfp = zfp_;
  d.lo = float(lo_), d.hi = float(hi_);
  v.setDims(info_.dims.x, info_.dims.y, info_.dims.z);
  v.cacheId = cacheId_;
  return v;
}

RangeGrid Layout::rangeGrid() const { return brickRangeGrid(view()); }

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  const Layout layout(info, sections);
  return decodeBricks(layout.view(), info.type, info.spacing);
}

}  // namespace voxwall::codec::zfp
