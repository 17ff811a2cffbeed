// Decode throughput and raycast time of the brick codecs' views (vq, ksvd) against the raw codec,
// on .vwz files:
//   voxwall_bench_vq [--size WxH] [--frames N] [--threads T] RAW.vwz VQ-OR-KSVD.vwz...
// For each file: full decode of every brick on one thread (Mvoxels/s per core), random voxel
// access through the view on one thread (Mvoxels/s), and the mean CPU raycast time of a frame
// (unshaded and shaded, the `mri` preset stretched over the data, a 3/4 orbit view) on T threads.
// Prints a markdown table.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/node/renderer.hpp>

using namespace voxwall;

namespace {

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

volatile float sink;

// The full-resolution brick view of a view with brick levels (ksvd), or the view itself.
template <class View>
const auto& brickLevel(const View& view) {
  if constexpr (requires {
                  requires codec::kernels::BrickView<std::decay_t<decltype(view.level[0])>>;
                })
    return view.level[0];
  else
    return view;
}

// Full decode: every brick of the volume, one thread; best of 3.
double decodeRate(const node::RenderVolume& v) {
  double best = 0;
  const glm::ivec3 dims = v.info().dims;
  for (int pass = 0; pass < 3; ++pass) {
    const auto start = std::chrono::steady_clock::now();
    float acc = 0;
    std::visit(
        [&](const auto& anyView) {
          const auto& view = brickLevel(anyView);
          using View = std::decay_t<decltype(view)>;
          if constexpr (codec::kernels::BrickView<View>) {
            constexpr int n = View::kSide;
            typename View::Value vox[View::kVoxels];
            for (int bz = 0; bz < (dims.z + n - 1) / n; ++bz)
              for (int by = 0; by < (dims.y + n - 1) / n; ++by)
                for (int bx = 0; bx < (dims.x + n - 1) / n; ++bx) {
                  view.decoder.decode(view.decoder.key(bx, by, bz), vox);
                  acc += float(vox[21]);
                }
          } else {  // raw: read every voxel through the view
            for (int z = 0; z < dims.z; ++z)
              for (int y = 0; y < dims.y; ++y)
                for (int x = 0; x < dims.x; ++x) acc += view.voxel(x, y, z);
          }
        },
        v.view());
    sink = acc;
    best = std::max(best, double(v.info().voxelCount()) / seconds(start) / 1e6);
  }
  return best;
}

// Random single voxels through the view (with its cache where it has one), one thread: 4M of
// them, or as many as 3 seconds take (a zfp brick of 16^3 is decoded for nearly every one).
double randomRate(const node::RenderVolume& v) {
  const glm::ivec3 d = v.info().dims;
  std::mt19937 rng(3);
  const int n = 4'000'000;
  std::vector<glm::ivec3> at(n);
  for (auto& p : at)
    p = {int(rng() % unsigned(d.x)), int(rng() % unsigned(d.y)), int(rng() % unsigned(d.z))};
  const auto start = std::chrono::steady_clock::now();
  float acc = 0;
  std::size_t done = at.size();
  std::visit(
      [&](const auto& anyView) {
        const auto& view = brickLevel(anyView);
        using View = std::decay_t<decltype(view)>;
        typename View::RayCache cache;
        for (std::size_t i = 0; i < at.size(); ++i) {
          const auto& p = at[i];
          if constexpr (codec::kernels::BrickView<View>)
            acc += view.voxel(p.x, p.y, p.z, cache);
          else
            acc += view.voxel(p.x, p.y, p.z);
          if ((i & 4095) == 4095 && seconds(start) > 3) {
            done = i + 1;
            break;
          }
        }
      },
      v.view());
  sink = acc;
  return double(done) / seconds(start) / 1e6;
}

double frameMs(const node::RenderVolume& v, int w, int h, int frames, int threads, bool shading) {
  node::RenderSettings s;
  s.shading = shading;
  node::Orbit orbit;
  const auto camera = node::orbitCamera(orbit, node::boundingRadius(v.info()));
  const auto tf =
      node::TransferFunction::preset("mri").rescaled(v.info().valueMin, v.info().valueMax);
  const auto plan = node::planFrame(v, camera, w, h, tf, s);
  auto backend = node::makeCpuBackend(threads);
  voxwall::Image image;
  backend->render(v, plan, {0, 0, w, h}, image);  // warm-up (fills the caches)
  const auto start = std::chrono::steady_clock::now();
  for (int f = 0; f < frames; ++f) backend->render(v, plan, {0, 0, w, h}, image);
  return 1000.0 * seconds(start) / frames;
}

std::string describe(const node::RenderVolume& v, const std::string& path) {
  const auto file = codec::ContainerFile::open(path);
  if (v.info().codec != codec::vq::VqCodecEntry::kId) {
    const std::string name = path.substr(path.find_last_of('/') + 1);
    return std::string(codec::codecName(v.info().codec)) + " " + name;
  }
  const codec::vq::Layout layout(file.info(), file.sections());
  std::string s = (layout.flags() & codec::vq::kCompressed) ? "vq rbuc" : "vq plain";
  s += layout.reduction() > 1 ? " 1/" + std::to_string(layout.reduction()) : " lossless";
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  int w = 1920, h = 1080, frames = 3, threads = 0;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--size" && i + 1 < argc) {
      std::sscanf(argv[++i], "%dx%d", &w, &h);
    } else if (a == "--frames" && i + 1 < argc) {
      frames = std::atoi(argv[++i]);
    } else if (a == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (a.starts_with("-")) {
      std::fprintf(stderr, "usage: %s [--size WxH] [--frames N] [--threads T] FILE.vwz...\n",
                   argv[0]);
      return 2;
    } else {
      files.push_back(a);
    }
  }
  std::printf(
      "| volume | bits/voxel | decode Mvox/s/core | random voxel Mvox/s | frame ms %dx%d | "
      "shaded frame ms |\n|---|---|---|---|---|---|\n",
      w, h);
  for (const auto& path : files) {
    const auto v = node::RenderVolume::open(path);
    const double bpv = 8.0 * double(v.storedBytes()) / double(v.info().voxelCount());
    std::printf("| %s | %.3f | %.0f | %.1f | %.0f | %.0f |\n", describe(v, path).c_str(), bpv,
                decodeRate(v), randomRate(v), frameMs(v, w, h, frames, threads, false),
                frameMs(v, w, h, frames, threads, true));
    std::fflush(stdout);
  }
  return 0;
}
