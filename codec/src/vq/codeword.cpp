// The vq codec's codewords: a brick's min and max, then its values relative to the min coded
// with recursive bottom-up coding (RBUC) after one of four predictors, or stored plain when that
// is shorter (the byte layout is documented in vq_codec.hpp); and the bit widths of the tables.
#include <algorithm>
#include <bit>
#include <stdexcept>
#include <string>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/core/errors.hpp>

#include "book.hpp"

namespace voxwall::codec::vq {

namespace {

int widthOf(std::uint32_t v) { return int(std::bit_width(v)); }  // 0 for 0

// Appends `count` values of `bits` bits, LSB first, to a byte-aligned stream.
class BitWriter {
 public:
  explicit BitWriter(std::vector<std::uint8_t>& out) : out_(out) {}
  void put(std::uint64_t value, int bits) {
    for (int i = 0; i < bits; ++i) {
      if (used_ == 0) out_.push_back(0);
      out_.back() |= std::uint8_t(((value >> i) & 1u) << used_);
      used_ = (used_ + 1) & 7;
    }
  }
  void align() { used_ = 0; }

 private:
  std::vector<std::uint8_t>& out_;
  int used_ = 0;
};

// The RBUC body of brick values u (relative to min) for transformation t: c2 header, c1s, c0s.
void rbucBody(const Brick& u, std::int32_t range, int t, std::vector<std::uint8_t>& out) {
  std::uint32_t c0[kN];
  Brick decoded{};  // the decoder's view of the values so far (equal to u: lossless)
  for (int i = 0; i < kN; ++i) {
    if (t == 0) {
      c0[i] = u[i];
    } else {
      const std::int32_t pred = kernels::vqPredict(decoded.data(), i, t, range);
      const std::int32_t r = std::int32_t(u[i]) - pred;
      c0[i] = (std::uint32_t(r) << 1) ^ std::uint32_t(r >> 31);  // zigzag
    }
    decoded[i] = u[i];
  }
  int c1[8], maxC1 = 0;
  for (int g = 0; g < 8; ++g) {
    std::uint32_t m = 0;
    for (int j = 0; j < 8; ++j) m = std::max(m, c0[g * 8 + j]);
    c1[g] = widthOf(m);
    maxC1 = std::max(maxC1, c1[g]);
  }
  const int c2 = widthOf(std::uint32_t(maxC1));
  out.push_back(std::uint8_t(c2 | (t << 6)));
  BitWriter w(out);
  for (int g = 0; g < 8; ++g) w.put(std::uint64_t(c1[g]), c2);
  for (int g = 0; g < 8; ++g) {
    w.align();
    for (int j = 0; j < 8; ++j) w.put(c0[g * 8 + j], c1[g]);
  }
}

}  // namespace

void plainCodeword(const Brick& b, int bits, std::vector<std::uint8_t>& out) {
  BitWriter w(out);
  for (int i = 0; i < kN; ++i) w.put(b[i], bits);
}

int bitsFor(std::uint64_t maxValue) { return std::max(1, int(std::bit_width(maxValue))); }

bool chooseIndirect(std::uint64_t entries, std::uint64_t codewords, std::uint64_t codebookBytes) {
  const int a = bitsFor(codewords > 0 ? codewords - 1 : 0);
  const int b = bitsFor(codebookBytes > 0 ? codebookBytes - 1 : 0);
  const std::uint64_t direct = (entries * std::uint64_t(b) + 7) / 8;
  const std::uint64_t indirect =
      (entries * std::uint64_t(a) + 7) / 8 + (codewords * std::uint64_t(b) + 7) / 8;
  return indirect < direct;
}

int bitDepth(const Volume& volume) {
  const auto [lo, hi] = memorySource(volume)->dataRange();
  return bitDepth(volume.type, lo, hi);
}

int bitDepth(ScalarType type, double lo, double hi) {
  switch (type) {
    case ScalarType::UInt8:
      return 8;
    case ScalarType::UInt16:
      return hi < 4096 ? 12 : 16;
    case ScalarType::Int16:
      return hi - lo < 4096 ? 12 : 16;
    case ScalarType::Float32:
      break;
  }
  throw std::invalid_argument(
      "vq codec: float32 volumes are not supported (the codec codes 8, 12 and 16-bit integers); "
      "use --codec raw");
}

int encodeCodeword(const Brick& brick, int bits, std::vector<std::uint8_t>& out, int transform) {
  const auto [loIt, hiIt] = std::minmax_element(brick.begin(), brick.end());
  const std::uint32_t lo = *loIt, hi = *hiIt;
  {
    BitWriter w(out);
    w.put(lo, bits);
    w.put(hi, bits);
  }
  if (lo == hi) return -1;
  Brick u;
  for (int i = 0; i < kN; ++i) u[i] = std::uint16_t(brick[i] - lo);
  const std::int32_t range = std::int32_t(hi - lo);
  // Code the body with each candidate transformation once and keep the shortest.
  std::vector<std::uint8_t> body, candidate;
  int best = -1;
  for (int t = transform < 0 ? 0 : transform; t <= (transform < 0 ? 3 : transform); ++t) {
    candidate.clear();
    rbucBody(u, range, t, candidate);
    if (best < 0 || candidate.size() < body.size()) best = t, body.swap(candidate);
  }
  if (body.size() >= std::size_t(1 + 8 * bits)) {
    out.push_back(std::uint8_t(kernels::kVqEscape));
    plainCodeword(brick, bits, out);
    return kernels::kVqEscape;
  }
  out.insert(out.end(), body.begin(), body.end());
  return best;
}

std::size_t codewordLength(const std::uint8_t* p, std::size_t available, int bits,
                           const std::string& source) {
  auto fail = [&](const std::string& what) -> std::size_t {
    throw FormatError(source, "section 'data': malformed codeword: " + what);
  };
  const std::size_t mm = std::size_t((2 * bits + 7) / 8);
  if (available < mm) return fail("truncated min/max");
  const auto lo = kernels::readBits(p, 0, bits),
             hi = kernels::readBits(p, std::uint64_t(bits), bits);
  if (lo > hi) return fail("min above max");
  if (lo == hi) return mm;
  if (available < mm + 1) return fail("truncated header");
  const int header = p[mm];
  if (header == kernels::kVqEscape) {
    const std::size_t n = mm + 1 + std::size_t(8 * bits);
    return n <= available ? n : fail("truncated raw brick");
  }
  const int c2 = header & 63;
  if (c2 > 5) return fail("c2 of " + std::to_string(c2) + " bits");
  std::size_t n = mm + 1 + std::size_t(c2);
  if (n > available) return fail("truncated c1 values");
  for (int g = 0; g < 8; ++g) {
    const int c1 = int(kernels::readBits(p + mm + 1, std::uint64_t(g * c2), c2));
    if (c1 > bits + 1) return fail("c1 of " + std::to_string(c1) + " bits");
    n += std::size_t(c1);
  }
  return n <= available ? n : fail("truncated values");
}
}  // namespace voxwall::codec::vq
