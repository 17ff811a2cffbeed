// The ksvd encoder's block codes in layout 2: quantizing, sizing and writing them.
#include "block_codes.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "format.hpp"

namespace voxwall::codec::ksvd {

void quantizeBrick(std::span<const SparseCode> codes, const float* y, std::span<const int> inGrid,
                   int m, int perBrick, float scale, double range, const CodeWidths& widths,
                   std::size_t c, CodedBricks& out) {
  const int qmax = maxQuantized(widths.coefBits);
  // The pairs' step (the DC atom's coefficient, the block's mean, is stored apart).
  float maxAbs = 0;
  for (const SparseCode& code : codes)
    for (std::size_t s = 1; s < code.coefficients.size(); ++s)
      maxAbs = std::max(maxAbs, std::abs(code.coefficients[s]));
  const float step = maxAbs > 0 ? maxAbs / float(qmax) : 1.0f / float(qmax);
  out.steps[c] = step * scale;
  const double meanLevels = double((1u << widths.meanBits) - 1u);
  std::vector<std::uint32_t>& means = out.means[c];
  std::vector<std::uint8_t>& counts = out.counts[c];
  std::vector<std::uint32_t>& pairs = out.pairs[c];
  means.assign(std::size_t(perBrick), 0);
  counts.assign(std::size_t(perBrick), 0);
  pairs.clear();
  for (std::size_t i = 0; i < inGrid.size(); ++i) {
    const SparseCode& code = codes[i];
    if (code.atoms.empty() || code.atoms[0] != 0)
      throw std::logic_error("ksvd: a block's code does not start with the DC atom");
    double mean = 0;
    for (int v = 0; v < m; ++v) mean += double(y[i * std::size_t(m) + std::size_t(v)]);
    mean = mean / m * double(scale);
    means[std::size_t(inGrid[i])] =
        range > 0 ? std::uint32_t(
                        std::clamp(std::lround(mean / range * meanLevels), 0l, long(meanLevels)))
                  : 0;
    int count = 0;
    for (std::size_t s = 1; s < code.atoms.size(); ++s) {
      const int q = std::clamp(int(std::lround(code.coefficients[s] / step)), -qmax, qmax);
      if (q == 0) continue;  // adds nothing
      pairs.push_back(packPair(code.atoms[s], q, widths.indexBits, widths.coefBits));
      ++count;
    }
    counts[std::size_t(inGrid[i])] = std::uint8_t(count);
  }
}

std::uint64_t blockTableBytes(std::uint64_t blocks, int meanBits) {
  return (blocks * std::uint64_t(meanBits) + 7) / 8 + (blocks + 7) / 8;
}

std::uint64_t codeBytes(const CodedBricks& codes, std::uint64_t blocks, const CodeWidths& widths) {
  return blockTableBytes(blocks, widths.meanBits) + (codes.pairCount + 7) / 8 +
         pairStreamBytes(codes.pairCount, widths.pairBits());
}

CodeSections codeSections(const CodedBricks& codes, int perBrick, const CodeWidths& widths) {
  CodeSections out;
  std::uint64_t countBits = 0, dcBits = 0, pairs = 0;
  for (std::size_t c = 0; c < codes.counts.size(); ++c) {
    for (int j = 0; j < perBrick; ++j) {
      for (int p = 0; p < codes.counts[c][std::size_t(j)]; ++p)
        appendBits(out.counts, countBits, 1, 1);
      appendBits(out.counts, countBits, 0, 1);
      appendBits(out.dc, dcBits, codes.means[c][std::size_t(j)], widths.meanBits);
    }
    for (const std::uint32_t word : codes.pairs[c])
      appendPair(out.pairs, pairs++, word, widths.pairBits());
  }
  return out;
}

}  // namespace voxwall::codec::ksvd
