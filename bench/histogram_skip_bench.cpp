// Would per-brick value histograms (COVRA's 64 bins, Gobbetti et al. 2012) let the raycaster skip
// more empty space than the value ranges every codec stores today? For one volume and a set of
// 1-D transfer functions, counts the skip cells (8^3 voxels, the raycaster's fine cells) and the
// bricks (32^3) that are empty -- every sample whose trilinear cell starts there is transparent --
// by four tests:
//   range      the cell's [min, max] over the voxels its samples read (what voxwall does)
//   hist64     64 bins over the volume's range marking the voxel values present: what the paper
//              stores; NOT sound for trilinear sampling (a sample between a 0 and a 255 voxel
//              has a value neither voxel has), shown for reference only
//   hist64/tri 64 bins marking every bin a trilinear cell's [min, max] overlaps: sound
//   exact      every trilinear cell's own [min, max]: the most any sound histogram could skip
// Prints a table; exits non-zero when it cannot read the volume.
//
//   voxwall_bench_histogram_skip [VOLUME FILE]   (default: a Marschner-Lobb 128^3 volume)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/node/transfer_function.hpp>

using namespace voxwall;

namespace {

struct Counts {
  std::size_t range = 0, hist = 0, histTri = 0, exact = 0, total = 0;
};

// Empty counts for cells of `side` voxels: a cell holds the trilinear cells whose lower corner
// lies in it (their corners reach one voxel further).
Counts countEmpty(const std::vector<float>& v, glm::ivec3 d, int side, float vlo, float vhi,
                  const node::HostLut& lut) {
  constexpr int kBins = 64;
  const float binWidth = (vhi - vlo) / float(kBins);
  auto bin = [&](float x) {
    return std::clamp(int((x - vlo) / (binWidth > 0 ? binWidth : 1.0f)), 0, kBins - 1);
  };
  // Per bin: can any value of it be visible?
  bool visible[kBins];
  for (int b = 0; b < kBins; ++b)
    visible[b] = lut.maxOpacity(vlo + float(b) * binWidth, vlo + float(b + 1) * binWidth) > 0;
  auto at = [&](int x, int y, int z) {
    x = std::min(x, d.x - 1), y = std::min(y, d.y - 1), z = std::min(z, d.z - 1);
    return v[(std::size_t(z) * std::size_t(d.y) + std::size_t(y)) * std::size_t(d.x) +
             std::size_t(x)];
  };
  Counts c;
  const glm::ivec3 cells = (d + side - 1) / side;
  for (int cz = 0; cz < cells.z; ++cz)
    for (int cy = 0; cy < cells.y; ++cy)
      for (int cx = 0; cx < cells.x; ++cx) {
        ++c.total;
        float lo = INFINITY, hi = -INFINITY;
        bool voxelBins[kBins] = {}, triBins[kBins] = {};
        bool exactEmpty = true;
        const int x0 = cx * side, y0 = cy * side, z0 = cz * side;
        for (int z = z0; z < std::min(z0 + side, d.z); ++z)
          for (int y = y0; y < std::min(y0 + side, d.y); ++y)
            for (int x = x0; x < std::min(x0 + side, d.x); ++x) {
              float tlo = INFINITY, thi = -INFINITY;
              for (int j = 0; j < 8; ++j) {
                const float s = at(x + (j & 1), y + ((j >> 1) & 1), z + (j >> 2));
                tlo = std::min(tlo, s), thi = std::max(thi, s);
                voxelBins[bin(s)] = true;
              }
              lo = std::min(lo, tlo), hi = std::max(hi, thi);
              for (int b = bin(tlo); b <= bin(thi); ++b) triBins[b] = true;
              if (exactEmpty && lut.maxOpacity(tlo, thi) > 0) exactEmpty = false;
            }
        bool histEmpty = true, triEmpty = true;
        for (int b = 0; b < kBins; ++b) {
          if (voxelBins[b] && visible[b]) histEmpty = false;
          if (triBins[b] && visible[b]) triEmpty = false;
        }
        c.range += lut.maxOpacity(lo, hi) <= 0;
        c.hist += histEmpty, c.histTri += triEmpty, c.exact += exactEmpty;
      }
  return c;
}

// A tent of opacity 0.8 over [a, b] of the value range (fractions), zero elsewhere.
node::TransferFunction window(double a, double b, double vlo, double vhi) {
  node::TransferFunction tf;
  const double span = vhi - vlo;
  tf.name = "window";
  tf.colors = {{vlo, 1, 1, 1}, {vhi, 1, 1, 1}};
  tf.opacities = {{vlo, 0},
                  {vlo + a * span, 0},
                  {vlo + 0.5 * (a + b) * span, 0.8},
                  {vlo + b * span, 0},
                  {vhi, 0}};
  return tf;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string spec = argc > 1 ? argv[1] : "Marschner-Lobb 128^3";
    const codec::Volume volume =
        argc > 1 ? codec::readVolume(spec) : codec::generateMarschnerLobb(128);
    std::vector<float> v(volume.voxelCount());
    codec::dispatchScalar(volume.type, [&](auto t) {
      const auto src = volume.as<decltype(t)>();
      for (std::size_t i = 0; i < v.size(); ++i) v[i] = float(src[i]);
    });
    const auto [mn, mx] = std::minmax_element(v.begin(), v.end());
    const float vlo = *mn, vhi = *mx;
    std::printf("%s: %dx%dx%d, values %g..%g\n\n", spec.c_str(), volume.dims.x, volume.dims.y,
                volume.dims.z, double(vlo), double(vhi));
    std::printf("| transfer function | cells | range | hist64 (unsound) | hist64/tri | exact |\n");
    std::printf("| --- | --- | --- | --- | --- | --- |\n");
    std::vector<std::pair<std::string, node::TransferFunction>> tfs;
    for (const std::string& name : node::TransferFunction::presetNames())
      tfs.emplace_back(name, node::TransferFunction::preset(name).rescaled(vlo, vhi));
    tfs.emplace_back("window 40-50%", window(0.4, 0.5, vlo, vhi));
    tfs.emplace_back("window 70-80%", window(0.7, 0.8, vlo, vhi));
    for (const auto& [name, tf] : tfs) {
      const node::HostLut lut = tf.bake(tf.domainMin(), tf.domainMax(), 1.0);
      for (int side : {8, 32}) {
        const Counts c = countEmpty(v, volume.dims, side, vlo, vhi, lut);
        auto pct = [&](std::size_t n) { return 100.0 * double(n) / double(c.total); };
        std::printf("| %s | %d^3 (%zu) | %.1f%% | %.1f%% | %.1f%% | %.1f%% |\n", name.c_str(), side,
                    c.total, pct(c.range), pct(c.hist), pct(c.histTri), pct(c.exact));
      }
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "voxwall_bench_histogram_skip: %s\n", e.what());
    return 1;
  }
}
