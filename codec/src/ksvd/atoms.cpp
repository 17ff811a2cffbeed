// The ksvd dictionary section (2) at a chosen width: the atoms' values as the encoder codes with
// them and the layout decodes them.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <voxwall/codec/ksvd_codec.hpp>

namespace voxwall::codec::ksvd {

namespace {
int largestLevel(int atomBits) { return (1 << (atomBits - 1)) - 1; }
}  // namespace

std::uint64_t dictionaryBytes(std::uint64_t atoms, int m, int atomBits) {
  if (atomBits == kWideAtomBits) return atoms * std::uint64_t(m) * 2;
  return atoms * 4 + (atoms * std::uint64_t(m) * std::uint64_t(atomBits) + 7) / 8;
}

std::vector<std::byte> dictionarySection(std::span<const float> values, int m, int atomBits) {
  if (atomBits < kMinAtomBits || atomBits > kWideAtomBits || m <= 0 || values.size() % m != 0)
    throw std::invalid_argument("ksvd: atoms of " + std::to_string(atomBits) + " bits (" +
                                std::to_string(kMinAtomBits) + ".." +
                                std::to_string(kWideAtomBits) + ")");
  const std::size_t atoms = values.size() / std::size_t(m);
  std::vector<std::byte> out;
  if (atomBits == kWideAtomBits) {
    out.resize(values.size() * 2);
    for (std::size_t i = 0; i < values.size(); ++i) {
      const auto v = std::int16_t(std::lround(std::clamp(values[i], -1.0f, 1.0f) * 32767.0f));
      std::memcpy(out.data() + 2 * i, &v, 2);
    }
    return out;
  }
  // Each atom's scale (its largest magnitude over the largest level), then every value in
  // atomBits bits, two's complement, LSB-first.
  const int top = largestLevel(atomBits);
  std::vector<float> scales(atoms);
  out.resize(atoms * 4);
  for (std::size_t a = 0; a < atoms; ++a) {
    float peak = 0;
    for (int i = 0; i < m; ++i) peak = std::max(peak, std::abs(values[a * std::size_t(m) + i]));
    scales[a] = peak / float(top);
    std::memcpy(out.data() + 4 * a, &scales[a], 4);
  }
  std::vector<std::byte> packed;
  std::uint64_t bits = 0;
  const std::uint32_t mask = (1u << atomBits) - 1u;
  for (std::size_t a = 0; a < atoms; ++a)
    for (int i = 0; i < m; ++i) {
      const float v = values[a * std::size_t(m) + i];
      const int q = scales[a] > 0 ? std::clamp(int(std::lround(v / scales[a])), -top, top) : 0;
      appendBits(packed, bits, std::uint32_t(q) & mask, atomBits);
    }
  out.insert(out.end(), packed.begin(), packed.end());
  return out;
}

std::vector<float> dictionaryValues(std::span<const std::byte> section, std::uint64_t atoms, int m,
                                    int atomBits) {
  if (section.size() != dictionaryBytes(atoms, m, atomBits))
    throw std::invalid_argument(std::to_string(section.size()) + " bytes for " +
                                std::to_string(atoms) + " atoms of " + std::to_string(m) + " " +
                                std::to_string(atomBits) + "-bit values");
  std::vector<float> values(atoms * std::uint64_t(m));
  if (atomBits == kWideAtomBits) {
    for (std::size_t i = 0; i < values.size(); ++i) {
      std::int16_t v;
      std::memcpy(&v, section.data() + 2 * i, 2);
      values[i] = float(v) / 32767.0f;
    }
    return values;
  }
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(section.data());
  const std::uint64_t first = atoms * 4;
  const kernels::KsvdBits packed{bytes + first, section.size() - first};
  for (std::uint64_t a = 0; a < atoms; ++a) {
    float scale;
    std::memcpy(&scale, bytes + 4 * a, 4);
    if (!std::isfinite(scale) || scale < 0)
      throw std::invalid_argument("atom " + std::to_string(a) + " has a scale of " +
                                  std::to_string(scale));
    for (int i = 0; i < m; ++i) {
      const std::uint64_t at = a * std::uint64_t(m) + std::uint64_t(i);
      const std::uint32_t raw = packed.field(at * std::uint64_t(atomBits), atomBits);
      // Sign-extend the two's complement field.
      const int q = int(raw << (32 - atomBits)) >> (32 - atomBits);
      values[at] = float(q) * scale;
    }
  }
  return values;
}

}  // namespace voxwall::codec::ksvd
