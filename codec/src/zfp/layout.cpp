// The zfp codec's reader: each brick's stream through libzfp, the sections' checks, the host view
// and the full decode.
#include <zfp.h>

#include <algorithm>
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

std::uint64_t maxStreamBits(const kernels::ZfpStreamParams& p, const BrickShape& shape) {
  return std::uint64_t(shape.blocks()) * std::max(p.maxbits, p.minbits);
}

namespace {
// Calls f(offset, bx, by, bz) for each 4^3 block of the brick (bx.. its voxels along each axis,
// 4 but at the brick's far faces), in zfp_compress's order.
template <class F>
void forEachBlock(const BrickShape& s, F&& f) {
  for (int z = 0; z < s.nz; z += 4)
    for (int y = 0; y < s.ny; y += 4)
      for (int x = 0; x < s.nx; x += 4)
        f(x + kBrick * (y + kBrick * z), std::min(4, s.nx - x), std::min(4, s.ny - y),
          std::min(4, s.nz - z));
}
constexpr std::ptrdiff_t kSy = kBrick, kSz = kBrick * kBrick;
}  // namespace

BrickBits compressBrick(const kernels::ZfpStreamParams& params, const float* in,
                        const BrickShape& shape) {
  BrickBits b;
  b.words.assign(maxStreamBits(params, shape) / 64 + 2, 0);
  Stream s;
  s.set(params);
  s.attach(b.words.data(), b.words.size() * 8);
  forEachBlock(shape, [&](int at, int bx, int by, int bz) {
    if (bx == 4 && by == 4 && bz == 4)
      b.bits += zfp_encode_block_strided_float_3(s.zfp, in + at, 1, kSy, kSz);
    else
      b.bits += zfp_encode_partial_block_strided_float_3(
          s.zfp, in + at, std::size_t(bx), std::size_t(by), std::size_t(bz), 1, kSy, kSz);
  });
  stream_flush(s.bits);
  // Its words only: the encoder holds a row of bricks, each allocated for zfp's largest block.
  b.words.resize((b.bits + 63) / 64);
  b.words.shrink_to_fit();
  return b;
}

BrickBits storeBrick(ScalarType type, const float* in, const BrickShape& shape) {
  BrickBits b;
  b.words.assign((storedBits(type, shape) + 63) / 64 + 1, 0);
  Stream s;
  s.attach(b.words.data(), b.words.size() * 8);
  const int width = int(8 * scalarBytes(type));
  for (int z = 0; z < shape.nz; ++z)
    for (int y = 0; y < shape.ny; ++y)
      for (int x = 0; x < shape.nx; ++x) {
        const float v = in[x + kBrick * (y + kBrick * z)];
        std::uint64_t bits = 0;
        dispatchScalar(type, [&](auto t) {
          using T = decltype(t);
          const T value = T(v);
          std::memcpy(&bits, &value, sizeof(T));
        });
        stream_write_bits(s.bits, bits, unsigned(width));
      }
  stream_flush(s.bits);
  b.bits = storedBits(type, shape);
  b.words.resize((b.bits + 63) / 64);
  return b;
}

void appendBits(std::vector<std::byte>& stream, std::uint64_t& bits, const BrickBits& b) {
  const unsigned shift = unsigned(bits % 64);
  const std::uint64_t first = bits / 64, words = (bits + b.bits + 63) / 64;
  stream.resize(words * 8, std::byte{0});
  const auto orWord = [&](std::uint64_t at, std::uint64_t v) {
    std::uint64_t w;  // a little-endian host (core/bytes.hpp)
    std::memcpy(&w, stream.data() + 8 * at, 8);
    w |= v;
    std::memcpy(stream.data() + 8 * at, &w, 8);
  };
  for (std::uint64_t i = 0; i < b.words.size(); ++i) {
    std::uint64_t v = b.words[i];
    const std::uint64_t left = b.bits - 64 * i;
    if (left < 64) v &= (std::uint64_t(1) << left) - 1;
    orWord(first + i, v << shift);
    if (shift && first + i + 1 < words) orWord(first + i + 1, v >> (64 - shift));
  }
  bits += b.bits;
}

void decodeBrick(const kernels::ZfpStreamParams& params, ScalarType type, bool stored,
                 const std::uint8_t* stream, std::uint64_t begin, std::uint64_t end,
                 const BrickShape& shape, float* out) {
  // zfp's bit reader trusts its input: on corrupt bits a block reads up to its bit budget, past
  // the brick's end, and the reader fetches a word ahead. It reads a copy of the brick's words in
  // a buffer that holds that bound (what lies past the brick's words is whatever an earlier brick
  // left there: a corrupt brick decodes to wrong values, clamped, never out of bounds).
  thread_local std::vector<std::uint64_t> scratch;
  const std::uint64_t firstWord = begin / 64, words = (end + 63) / 64 - firstWord;
  const std::uint64_t bound =
      words + (stored ? storedBits(type, shape) : maxStreamBits(params, shape)) / 64 + 3;
  if (scratch.size() < bound) scratch.resize(bound);
  if (words) std::memcpy(scratch.data(), stream + 8 * firstWord, 8 * words);
  scratch[words] = scratch[words + 1] = 0;
  Stream s;
  s.set(params);
  s.attach(scratch.data(), bound * 8);
  stream_rseek(s.bits, begin % 64);
  if (stored) {
    const unsigned width = unsigned(8 * scalarBytes(type));
    dispatchScalar(type, [&](auto t) {
      using T = decltype(t);
      for (int z = 0; z < shape.nz; ++z)
        for (int y = 0; y < shape.ny; ++y)
          for (int x = 0; x < shape.nx; ++x) {
            const std::uint64_t bits = stream_read_bits(s.bits, width);
            T value;
            std::memcpy(&value, &bits, sizeof(T));
            out[x + kBrick * (y + kBrick * z)] = float(value);
          }
    });
    return;
  }
  forEachBlock(shape, [&](int at, int bx, int by, int bz) {
    if (bx == 4 && by == 4 && bz == 4)
      zfp_decode_block_strided_float_3(s.zfp, out + at, 1, kSy, kSz);
    else
      zfp_decode_partial_block_strided_float_3(s.zfp, out + at, std::size_t(bx), std::size_t(by),
                                               std::size_t(bz), 1, kSy, kSz);
  });
}

// ---- the host view's decoder ------------------------------------------------------------

}  // namespace voxwall::codec::zfp

namespace voxwall::codec::kernels {

void zfpDecodeBrick(const ZfpDecoder& d, std::uint64_t brick, float* out) {
  using namespace voxwall::codec::zfp;
  const Index index{d.index, d.rows, std::uint64_t(d.bricksX), d.entryBits};
  const BrickShape s = brickShape({d.dimX, d.dimY, d.dimZ}, brick);
  const ScalarType type = ScalarType(d.type);
  std::fill(out, out + kBrickVoxels, 0.0f);
  decodeBrick(d.zfp, type, index.stored(brick), d.stream, index.begin(brick), index.end(brick), s,
              out);
  finishBrick(out, s, d.lo, d.hi, type != ScalarType::Float32);
}

}  // namespace voxwall::codec::kernels

namespace voxwall::codec::zfp {

// ---- the sections ---------------------------------------------------------------------------

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  cacheId_ = mintCacheIds();
  const glm::ivec3 g = brickGrid(info.dims);
  bricks_ = std::uint64_t(g.x) * std::uint64_t(g.y) * std::uint64_t(g.z);
  rows_ = std::uint64_t(g.y) * std::uint64_t(g.z);
  readParams(sections);
  checkIndex(sections);
}

void Layout::readParams(const SectionSet& sections) {
  params_ = sections.get(kParams, "params");
  ByteReader r(params_, sections.source, "section 'params'");
  const auto mode = r.get<std::uint32_t>();
  zfp_.minbits = r.get<std::uint32_t>(), zfp_.maxbits = r.get<std::uint32_t>();
  zfp_.maxprec = r.get<std::uint32_t>(), zfp_.minexp = r.get<std::int32_t>();
  const auto entryBits = r.get<std::uint32_t>();
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
  // 0 in files from before the entries were packed: a u32 each.
  if (entryBits == 1 || entryBits > 32)
    fail("index entries of " + std::to_string(entryBits) + " bits (2..32, or 0 for 32)");
  entryBits_ = entryBits == 0 ? 32 : int(entryBits);
  if (!(lo_ <= hi_) || !std::isfinite(lo_) || !std::isfinite(hi_) ||
      std::abs(lo_) > std::numeric_limits<float>::max() ||
      std::abs(hi_) > std::numeric_limits<float>::max())
    fail("value range " + std::to_string(lo_) + ".." + std::to_string(hi_) + " is not finite");
  if (storedBricks_ > bricks_) fail("more stored bricks than bricks");
}

// Every row's offset and every brick's: in order, inside the stream, each brick exactly its
// voxels' bits (stored) or between what zfp writes for its blocks at least (minbits, 1 bit at
// the least) and at most (maxbits).
void Layout::checkIndex(const SectionSet& sections) {
  index_ = sections.get(kIndex, "index");
  stream_ = sections.get(kStream, "stream");
  ByteReader r(index_, sections.source, "section 'index'");
  auto fail = [&](const std::string& what) { r.fail(what); };
  const std::uint64_t expected = Index::bytes(rows_, bricks_, entryBits_);
  if (index_.size() != expected)
    fail(std::to_string(index_.size()) + " bytes for " + std::to_string(rows_) + " rows and " +
         std::to_string(bricks_) + " bricks of " + std::to_string(entryBits_) + " bits, not " +
         std::to_string(expected));
  const Index index = this->index();
  const std::uint64_t streamBits = index.rowBase(rows_);
  if (index.rowBase(0) != 0) fail("the first row does not start at bit 0");
  if ((streamBits + 63) / 64 * 8 != stream_.size())
    fail("the stream ends at bit " + std::to_string(streamBits) + ", not in its last word of " +
         std::to_string(stream_.size()) + " bytes");
  for (std::uint64_t row = 0; row < rows_; ++row)
    if (index.rowBase(row + 1) < index.rowBase(row) ||
        index.rowBase(row + 1) - index.rowBase(row) > kMaxRowBits)
      fail("row " + std::to_string(row) + "'s bits are out of order");
  std::uint64_t stored = 0;
  for (std::uint64_t i = 0; i < bricks_; ++i) {
    const std::uint64_t begin = index.begin(i), end = index.end(i);
    const std::string brick = "brick " + std::to_string(i);
    if (i % index.bricksX == 0 && begin != index.rowBase(i / index.bricksX))
      fail(brick + " does not start its row");
    if (end < begin) fail(brick + " ends before it starts");
    const BrickShape s = brickShape(info_.dims, i);
    if (index.stored(i)) {
      ++stored;
      if (end - begin != storedBits(info_.type, s))
        fail(brick + " is stored in " + std::to_string(end - begin) + " bits, not " +
             std::to_string(storedBits(info_.type, s)));
    } else if (end - begin > maxStreamBits(zfp_, s) ||
               end - begin < std::uint64_t(s.blocks()) * std::max(1u, zfp_.minbits)) {
      fail(brick + "'s " + std::to_string(end - begin) + " bits are not what zfp writes for " +
           std::to_string(s.blocks()) + " blocks");
    }
  }
  if (stored != storedBricks_)
    fail(std::to_string(stored) + " stored bricks, the params say " +
         std::to_string(storedBricks_));
}

Index Layout::index() const {
  return {reinterpret_cast<const std::uint8_t*>(index_.data()), rows_,
          std::uint64_t(brickGrid(info_.dims).x), entryBits_};
}

kernels::ZfpView Layout::view() const {
  kernels::ZfpView v;
  kernels::ZfpDecoder& d = v.decoder;
  d.index = reinterpret_cast<const std::uint8_t*>(index_.data());
  d.stream = reinterpret_cast<const std::uint8_t*>(stream_.data());
  d.rows = rows_;
  d.entryBits = entryBits_;
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

RangeGrid Layout::rangeGrid() const { return brickRangeGrid(view(), info_.type); }

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  const Layout layout(info, sections);
  return decodeBricks(layout.view(), info.type, info.spacing);
}

}  // namespace voxwall::codec::zfp
