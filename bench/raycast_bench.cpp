// Google Benchmark of the CPU raycaster: one 1920x1080 frame of the MRI template (or a generated
// phantom when mricron-data is missing) at a 1/4-voxel step, with the transfer function of the
// VTK comparison (bench/data/vtk-comparison-tf.json). Reports samples per second.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/node/renderer.hpp>

using namespace voxwall;

namespace {

const node::RenderVolume& volume() {
  static const node::RenderVolume v = [] {
    const char* mri = "/usr/share/mricron/templates/ch2better.nii.gz";
    return std::filesystem::exists(mri)
               ? node::RenderVolume::open(mri)
               : node::RenderVolume::fromVolume(codec::generateSheppLogan(256));
  }();
  return v;
}

node::TransferFunction comparisonTf() {
  node::TransferFunction tf;
  tf.colors = {{0, 0, 0, 0}, {255, 1, 1, 1}};
  tf.opacities = {{0, 0}, {40, 0}, {255, 0.8}};
  return tf;
}

// Args: threads, shading (0/1), empty-space skipping (0/1), gradients (0: six samples per
// shaded sample, 1: cell gradients), packets (0: one ray at a time, 1: SIMD packets).
void BM_RaycastFrame(benchmark::State& state) {
  const int threads = int(state.range(0));
  node::RenderSettings settings;
  settings.shading = state.range(1) != 0;
  settings.emptySpaceSkipping = state.range(2) != 0;
  settings.cellGradients = state.range(3) != 0;
  node::Orbit orbit;  // 3/4 view: azimuth 30, elevation 20
  const auto camera = node::orbitCamera(orbit, node::boundingRadius(volume().info()));
  const auto plan = node::planFrame(volume(), camera, 1920, 1080, comparisonTf(), settings);
  auto backend = node::makeCpuBackend(threads, state.range(4) != 0);
  state.SetLabel(backend->name());
  voxwall::Image image;
  std::uint64_t samples = 0;
  for (auto _ : state) {
    samples += backend->render(volume(), plan, {0, 0, 1920, 1080}, image).samples;
    benchmark::DoNotOptimize(image.pixels.data());
  }
  state.counters["Msamples/s"] =
      benchmark::Counter(double(samples) / 1e6, benchmark::Counter::kIsRate);
  state.counters["Msamples/s/thread"] =
      benchmark::Counter(double(samples) / 1e6 / threads, benchmark::Counter::kIsRate);
  state.counters["empty_cells"] = plan.emptyFraction;
}

BENCHMARK(BM_RaycastFrame)
    ->ArgNames({"threads", "shading", "skip", "cell_gradients", "packets"})
    ->Args({1, 0, 1, 1, 0})
    ->Args({1, 0, 1, 1, 1})
    ->Args({1, 1, 1, 1, 0})
    ->Args({1, 1, 1, 1, 1})
    ->Args({2, 0, 1, 1, 0})
    ->Args({2, 0, 1, 1, 1})
    ->Args({2, 0, 0, 1, 1})
    ->Args({2, 1, 1, 0, 1})
    ->Args({2, 1, 1, 1, 0})
    ->Args({2, 1, 1, 1, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
