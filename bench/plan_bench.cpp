// What a transfer-function change costs a rank: the range grid every rank keeps (packed) against
// the same grid unpacked, and the time to make a frame's skip grids anew (planFrame without a plan
// to reuse, which walks the packed ranges on every core), with the ranges walked on one thread
// unpacked and packed for comparison. Same files, same run.
//   voxwall_bench_plan [--repeat N] FILE.vwz...
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>
#include <voxwall/node/renderer.hpp>

using namespace voxwall;

namespace {

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

template <class F>
double medianMs(int repeat, F&& f) {
  std::vector<double> times;
  for (int i = 0; i < repeat; ++i) {
    const auto start = std::chrono::steady_clock::now();
    f();
    times.push_back(msSince(start));
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  int repeat = 5;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc)
      repeat = std::max(1, std::atoi(argv[++i]));
    else
      files.push_back(a);
  }
  if (files.empty()) {
    std::fprintf(stderr, "usage: voxwall_bench_plan [--repeat N] FILE.vwz...\n");
    return 2;
  }
  node::TransferFunction tf;  // the VTK comparison's: zero below 40
  tf.colors = {{0, 0, 0, 0}, {255, 1, 1, 1}};
  tf.opacities = {{0, 0}, {40, 0}, {255, 0.8}};
  const node::RenderSettings settings;
  node::Orbit orbit;
  std::printf(
      "| file | cells | ranges unpacked | packed | walk unpacked | walk packed | plan anew |\n"
      "|---|---|---|---|---|---|---|\n");
  for (const std::string& file : files) {
    try {
      const node::RenderVolume volume = node::RenderVolume::open(file);
      const codec::RangeGrid unpacked = volume.payload().rangeGrid();
      const node::Camera camera = node::orbitCamera(orbit, node::boundingRadius(volume.info()));
      volatile float sink = 0;
      const double walk = medianMs(repeat, [&] {
        float s = 0;
        unpacked.forEach([&](std::size_t, float lo, float hi) { s += hi - lo; });
        sink = s;
      });
      const double walkPacked = medianMs(repeat, [&] {
        float s = 0;
        volume.ranges().forEach([&](std::size_t, float lo, float hi) { s += hi - lo; });
        sink = s;
      });
      const double plan = medianMs(repeat, [&] {
        const node::FramePlan p = node::planFrame(volume, camera, 1920, 1080, tf, settings);
        sink = float(p.fineEmptyFraction);
      });
      std::printf("| %s | %zu | %.1f MiB | %.1f MiB | %.0f ms | %.0f ms | %.0f ms |\n",
                  file.c_str(), unpacked.cellCount(), double(unpacked.bytes()) / 1048576.0,
                  double(volume.ranges().bytes()) / 1048576.0, walk, walkPacked, plan);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "voxwall_bench_plan: %s\n", e.what());
      return 1;
    }
  }
  return 0;
}
