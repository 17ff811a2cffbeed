// The vq codec's k-means (furthest-first init with a lazy queue, norm-bound pruning, changed-centre
// bookkeeping) against the same clustering done plainly (brute-force furthest-first, then Lloyd
// checking every centre), on the unique 4^3 bricks of a volume:
//   voxwall_bench_vq_kmeans VOLUME [--points N] [--reductions 2,16,128] [--iterations I]
// Both return the same centres (a unit test checks it); this prints time and distance counts.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <vector>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/vq_kmeans.hpp>

using namespace voxwall::codec;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s VOLUME [--points N] [--reductions 2,16,128] [--iterations I]\n",
                 argv[0]);
    return 2;
  }
  std::size_t maxPoints = 10000;
  int iterations = 20;
  std::vector<int> reductions = {2, 16, 128};
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--points") maxPoints = std::size_t(std::atol(argv[i + 1]));
    if (a == "--iterations") iterations = std::atoi(argv[i + 1]);
    if (a == "--reductions") {
      reductions.clear();
      for (const char* p = argv[i + 1]; *p;) {
        reductions.push_back(std::atoi(p));
        while (*p && *p != ',') ++p;
        if (*p == ',') ++p;
      }
    }
  }
  const Volume v = readVolume(argv[1]);
  if (v.type != ScalarType::UInt8 && v.type != ScalarType::UInt16) {
    std::fprintf(stderr, "needs uint8 or uint16 data\n");
    return 1;
  }
  // Unique non-constant bricks, first come first served, with their counts.
  std::map<vq::Point, std::uint32_t> index;
  std::vector<vq::Point> points;
  std::vector<std::uint32_t> weights;
  for (int bz = 0; bz + 4 <= v.dims.z && points.size() < maxPoints; bz += 4)
    for (int by = 0; by + 4 <= v.dims.y; by += 4)
      for (int bx = 0; bx + 4 <= v.dims.x; bx += 4) {
        vq::Point p;
        int i = 0;
        for (int z = 0; z < 4; ++z)
          for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x)
              p[i++] = std::uint16_t(v.valueAt(v.index(bx + x, by + y, bz + z)));
        if (p[0] == p[63] && std::equal(p.begin() + 1, p.end(), p.begin())) continue;
        auto [it, inserted] = index.try_emplace(p, std::uint32_t(points.size()));
        if (inserted) {
          if (points.size() == maxPoints) continue;
          points.push_back(p), weights.push_back(0);
        }
        ++weights[it->second];
      }
  std::printf("%zu unique non-constant bricks of %s, %d iterations at most\n\n", points.size(),
              argv[1], iterations);
  std::printf(
      "| reduction | k | pruned s | plain s | speed-up | distances computed (pruned) | skipped "
      "by norm bound | computed (plain) |\n|---|---|---|---|---|---|---|---|\n");
  for (int r : reductions) {
    const std::size_t k = std::max<std::size_t>(1, points.size() / std::size_t(r));
    voxwall::Progress quiet;
    auto t0 = std::chrono::steady_clock::now();
    const auto fast = vq::kmeans(points, weights, k, iterations, 1, quiet);
    const double fastS =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    t0 = std::chrono::steady_clock::now();
    const auto plain = vq::kmeansBruteForce(points, weights, k, iterations);
    const double plainS =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("| 1/%d | %zu | %.2f | %.2f | %.0fx | %.3g | %.3g | %.3g |%s\n", r, k, fastS,
                plainS, plainS / fastS, double(fast.computed), double(fast.skipped),
                double(plain.computed),
                fast.assignment == plain.assignment ? "" : " (assignments differ!)");
    std::fflush(stdout);
  }
  return 0;
}
