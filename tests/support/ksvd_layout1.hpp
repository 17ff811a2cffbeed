// A ksvd file in layout 1, as the encoder wrote it before layout 2 (a count byte per block; a
// block's mean as the DC atom's pair, first among its pairs when its coefficient is not 0), made
// from a file of layout 2, and layout 1's decoder as it was, for the tests that read old files.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <voxwall/codec/ksvd_codec.hpp>

#include "sections.hpp"

namespace voxwall::test {

namespace ksvd_layout1 {
inline std::uint32_t get32(const std::vector<std::byte>& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}
inline codec::kernels::KsvdBits bitsOf(const std::vector<std::byte>& b) {
  return {reinterpret_cast<const std::uint8_t*>(b.data()), b.size()};
}
}  // namespace ksvd_layout1

// The bricks' steps and the pairs are kept; each block's mean becomes the DC atom's pair (its
// coefficient rounded to the brick's step, clamped to the pair's width); the atoms are stored at
// 16 bits, as every file of layout 1 stores them.
inline codec::CompressedVolume asKsvdLayout1(codec::CompressedVolume c) {
  namespace ksvd = codec::ksvd;
  using ksvd_layout1::get32;
  auto& params = section(c, ksvd::kParams);
  const int side = int(get32(params, 0)), n = int(get32(params, 4));
  const int indexBits = int(get32(params, 16)), coefBits = int(get32(params, 64));
  const int meanBits = int(get32(params, 72));
  const int atomBits = params.size() >= 80 ? int(get32(params, 76)) : ksvd::kWideAtomBits;
  if (get32(params, 68) != 2) throw std::logic_error("not a ksvd file of layout 2");
  auto& dictionary = section(c, ksvd::kDictionary);
  dictionary = ksvd::dictionarySection(
      ksvd::dictionaryValues(dictionary, get32(params, 8), side * side * side, atomBits),
      side * side * side, ksvd::kWideAtomBits);
  std::int16_t dcAtom;
  std::memcpy(&dcAtom, section(c, ksvd::kDictionary).data(), 2);
  const double a0 = double(dcAtom) / 32767.0;
  const auto dc = ksvd_layout1::bitsOf(section(c, ksvd::kDc));
  const auto unary = ksvd_layout1::bitsOf(section(c, ksvd::kCounts));
  const auto pairs = ksvd_layout1::bitsOf(section(c, ksvd::kPairs));
  const auto& bricks = section(c, ksvd::kBricks);
  const std::uint64_t perBrick = std::uint64_t(n * n * n);
  const int pairBits = indexBits + coefBits, qmax = ksvd::maxQuantized(coefBits);
  std::vector<std::byte> counts, out;
  std::uint64_t countBit = 0, pairIn = 0, pairOut = 0, block = 0;
  for (std::size_t at = 0; at < bricks.size(); at += 16) {
    if (get32(bricks, at + 12) == 0xFFFFFFFFu) continue;
    float lo, hi, step;
    std::memcpy(&lo, bricks.data() + at, 4), std::memcpy(&hi, bricks.data() + at + 4, 4);
    std::memcpy(&step, bricks.data() + at + 8, 4);
    for (std::uint64_t j = 0; j < perBrick; ++j, ++block) {
      const double mean = double(dc.field(block * std::uint64_t(meanBits), meanBits)) *
                          (double(hi) - double(lo)) / double((1u << meanBits) - 1u);
      // A pair's contribution to each voxel is q x step x the DC atom's value.
      const int q =
          int(std::clamp(std::lround(mean / (double(step) * a0)), -long(qmax), long(qmax)));
      int learned = 0;
      while (unary.field(countBit, 1)) ++learned, ++countBit;
      ++countBit;
      if (q != 0)
        ksvd::appendPair(out, pairOut++, ksvd::packPair(0, q, indexBits, coefBits), pairBits);
      for (int p = 0; p < learned; ++p, ++pairIn)
        ksvd::appendPair(out, pairOut++, pairs.field(pairIn * std::uint64_t(pairBits), pairBits),
                         pairBits);
      counts.push_back(std::byte(std::uint8_t(learned + (q != 0))));
    }
  }
  params.resize(68);  // no layout, mean or atom fields
  std::memcpy(params.data() + 32, &pairOut, 8);
  section(c, ksvd::kCounts) = std::move(counts);
  section(c, ksvd::kPairs) = std::move(out);
  std::erase_if(c.sections, [](const auto& s) { return s.first == ksvd::kDc; });
  return c;
}

}  // namespace voxwall::test
