// Random access into the VQ codec's bricks (Guthe & Goesele), on the host or on a device:
// offset volume -> (index table) -> codeword, and the RBUC codeword decoder; the caches, corners
// and sampling are CachedBrickView's. The encoder side
// and the byte layout are documented in vq_codec.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#if !defined(__CUDA_ARCH__)
#include <bit>
#include <cstring>
#endif
#include <voxwall/codec/kernels/cached_brick_view.hpp>

namespace voxwall::codec::kernels {

inline constexpr int kVqBrick = 4;  // voxels per brick side
inline constexpr int kVqBrickVoxels = 64;
inline constexpr int kVqEscape = 255;  // RBUC header byte: the raw voxels follow

// The 8 bytes at `q` as a little-endian word.
VOXWALL_HD_INLINE std::uint64_t loadWord(const std::uint8_t* q) {
#if defined(__CUDA_ARCH__)
  std::uint64_t word = 0;
  for (int i = 0; i < 8; ++i) word |= std::uint64_t(q[i]) << (8 * i);
  return word;
#else
  static_assert(std::endian::native == std::endian::little, "hosts are little-endian");
  std::uint64_t word;
  std::memcpy(&word, q, 8);
  return word;
#endif
}

// Reads `bits` (0..57) bits at bit offset `bit` of a little-endian bit stream. The stream must
// have 8 readable bytes past the byte that holds its last bit (the encoder pads every array).
VOXWALL_HD_INLINE std::uint64_t readBits(const std::uint8_t* p, std::uint64_t bit, int bits) {
  const std::uint64_t word = loadWord(p + (bit >> 3));
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

// vqPredict for a transformation known at compile time, with the voxel's position within the
// brick spelled out: the same prediction, without the loops over axes and subsets (the decoder's
// inner loop; vqPredict stays the definition the encoder uses).
template <int T>
VOXWALL_HD_INLINE std::int32_t vqPredictAt(const std::uint16_t* u, int i, std::int32_t range) {
  const bool ax = (i & 3) != 0, ay = ((i >> 2) & 3) != 0, az = (i >> 4) != 0;
  std::int32_t pred = 0;
  if constexpr (T == 1) {
    pred = ax ? u[i - 1] : ay ? u[i - 4] : az ? u[i - 16] : 0;
  } else if constexpr (T == 2) {
    if (ax && ay)
      pred = std::int32_t(u[i - 1]) + std::int32_t(u[i - 4]) - std::int32_t(u[i - 5]);
    else
      pred = ax ? u[i - 1] : ay ? u[i - 4] : az ? u[i - 16] : 0;
  } else {
    if (ax) pred += u[i - 1];
    if (ay) pred += u[i - 4];
    if (az) pred += u[i - 16];
    if (ax && ay) pred -= u[i - 5];
    if (ax && az) pred -= u[i - 17];
    if (ay && az) pred -= u[i - 20];
    if (ax && ay && az) pred += u[i - 21];
  }
  return pred < 0 ? 0 : (pred > range ? range : pred);
}

// The eight groups of a predicted codeword (transformation T): group g's code width at `widths`
// (c2 bits each), its codes in the groups' bytes at `codes`. Values relative to the minimum.
template <int T>
VOXWALL_HD_INLINE void vqDecodeGroups(const std::uint8_t* widths, int c2, const std::uint8_t* codes,
                                      std::int32_t range, std::uint16_t* out) {
  for (int g = 0; g < 8; ++g) {
    const int c1 = int(readBits(widths, std::uint64_t(g) * std::uint64_t(c2), c2));
    for (int j = 0; j < 8; ++j) {
      const int i = g * 8 + j;
      const std::uint32_t code =
          std::uint32_t(readBits(codes, std::uint64_t(j) * std::uint64_t(c1), c1));
      if constexpr (T == 0)
        out[i] = std::uint16_t(code);
      else
        out[i] = std::uint16_t(vqPredictAt<T>(out, i, range) + std::int32_t(zigzagDecode(code)));
    }
    codes += c1;
  }
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
  switch (t) {
    case 0:
      vqDecodeGroups<0>(p, c2, c0, range, out);
      break;
    case 1:
      vqDecodeGroups<1>(p, c2, c0, range, out);
      break;
    case 2:
      vqDecodeGroups<2>(p, c2, c0, range, out);
      break;
    default:
      vqDecodeGroups<3>(p, c2, c0, range, out);
      break;
  }
  for (int i = 0; i < kVqBrickVoxels; ++i) out[i] = std::uint16_t(out[i] + lo);
}

// Decodes one plain (bit-packed) codeword.
VOXWALL_HD_INLINE void vqDecodePlain(const std::uint8_t* p, int bits, std::uint16_t* out) {
  for (int i = 0; i < kVqBrickVoxels; ++i)
    out[i] = std::uint16_t(readBits(p, std::uint64_t(i) * std::uint64_t(bits), bits));
}

// The codec's half of the view (a CachedBrickView decoder). `data` holds the offset volume,
// `book` the index table (indirect mapping only) and the codebook at the byte offsets below: the
// same bytes in a single volume's file, a section of its own that a series' steps share; they
// point into host or device memory and are not owned.
struct VqDecoder {
  static constexpr int kBrickSide = 4;  // 4^3 bricks
  using Value = std::uint16_t;          // the data's unsigned values

  const std::uint8_t* data = nullptr;
  const std::uint8_t* book = nullptr;
  std::uint64_t indexTableAt = 0, codebookAt = 0;  // byte offsets into book
  int bricksX = 0, bricksY = 0;
  int bits = 8;         // data bit depth
  int offsetBits = 1;   // bits per offset-volume entry
  int addressBits = 0;  // bits per index-table entry (indirect mapping)
  bool compressed = false, indirect = false;
  float bias = 0;  // added to every decoded value (int16 data)

  // Byte address in the codebook of brick (bx, by, bz)'s codeword: equal addresses decode to
  // equal voxels.
  VOXWALL_HD_INLINE std::uint64_t key(int bx, int by, int bz) const {
    const std::uint64_t brick =
        (std::uint64_t(bz) * std::uint64_t(bricksY) + std::uint64_t(by)) * std::uint64_t(bricksX) +
        std::uint64_t(bx);
    const std::uint64_t entry = readBits(data, brick * std::uint64_t(offsetBits), offsetBits);
    if (!compressed) return entry * std::uint64_t(8 * bits);  // 64 voxels of `bits` bits
    if (!indirect) return entry;
    return readBits(book + indexTableAt, entry * std::uint64_t(addressBits), addressBits);
  }

  VOXWALL_HD_INLINE void decode(std::uint64_t address, std::uint16_t* out) const {
    const std::uint8_t* p = book + codebookAt + address;
    if (compressed)
      vqDecodeCodeword(p, bits, out);
    else
      vqDecodePlain(p, bits, out);
  }

  VOXWALL_HD_INLINE float scalar(std::uint16_t v) const { return float(v) + bias; }
};

using VqView = CachedBrickView<VqDecoder>;

static_assert(std::is_trivially_copyable_v<VqView>);

}  // namespace voxwall::codec::kernels
