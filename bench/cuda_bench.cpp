// The CUDA backend against the CPU backend on the same volumes, views and frames: per volume and
// shading, the first frame (which uploads the volume), then the median of the next frames, the
// samples per second of each backend, the CPU/CUDA ratio, and how far the pictures are apart
// (PSNR and the largest channel difference). CUDA runs both ways of sampling a compressed volume
// (node::DeviceDecode): decoded whole into raw bricks, and decoding blocks per ray. Needs a CUDA
// device: without one it says why and exits with status 2.
//
//   voxwall_bench_cuda [--frames N] [--size WxH] [--cpu-threads N] [--phantom N]... FILE...
//
// FILE: a .vwz or any volume voxwall reads. --phantom N adds a generated N^3 Shepp-Logan phantom
// (uint8, raw) made in memory, for a volume larger than the files one carries around.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>
#include <voxwall/codec/generators.hpp>
#include <voxwall/node/renderer.hpp>

using namespace voxwall;

namespace {

struct Options {
  int frames = 10;
  int width = 1920, height = 1080;
  int cpuThreads = 0;
  std::vector<int> phantoms;
  std::vector<std::string> files;
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "voxwall_bench_cuda: %s\nusage: voxwall_bench_cuda [--frames N] [--size WxH] "
               "[--cpu-threads N] [--phantom N]... FILE...\n",
               why);
  std::exit(1);
}

int positive(const char* text, const char* what) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (!end || *end || v <= 0 || v > 100000) usage(what);
  return int(v);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool hasValue = i + 1 < argc;
    if (a == "--frames" && hasValue) {
      o.frames = positive(argv[++i], "--frames wants a positive whole number");
    } else if (a == "--size" && hasValue) {
      if (std::sscanf(argv[++i], "%dx%d", &o.width, &o.height) != 2 || o.width <= 0 ||
          o.height <= 0)
        usage("--size wants WxH");
    } else if (a == "--cpu-threads" && hasValue) {
      o.cpuThreads = positive(argv[++i], "--cpu-threads wants a positive whole number");
    } else if (a == "--phantom" && hasValue) {
      o.phantoms.push_back(positive(argv[++i], "--phantom wants a size"));
    } else if (a.starts_with("--")) {
      usage(("unknown option or missing value: " + a).c_str());
    } else {
      o.files.push_back(a);
    }
  }
  if (o.files.empty() && o.phantoms.empty()) usage("no volume given");
  return o;
}

struct Timed {
  double firstMs = 0, medianMs = 0;
  std::uint64_t samples = 0;  // of one frame
  Image image;
};

Timed timeFrames(node::Backend& backend, const node::RenderVolume& volume,
                 const node::FramePlan& plan, const Options& o) {
  Timed t;
  const Rect screen{0, 0, o.width, o.height};
  std::vector<double> ms;
  for (int f = 0; f <= o.frames; ++f) {
    const auto start = std::chrono::steady_clock::now();
    t.samples = backend.render(volume, plan, screen, t.image).samples;
    const double elapsed =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (f == 0)
      t.firstMs = elapsed;
    else
      ms.push_back(elapsed);
  }
  std::sort(ms.begin(), ms.end());
  t.medianMs = ms[ms.size() / 2];
  return t;
}

// PSNR over the RGB channels (255 peak) and the largest channel difference.
std::pair<double, int> compare(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) return {0.0, 255};
  double squared = 0;
  int worst = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i)
    for (int c = 0; c < 24; c += 8) {
      const int d = int((a.pixels[i] >> c) & 0xFF) - int((b.pixels[i] >> c) & 0xFF);
      squared += double(d) * d;
      worst = std::max(worst, std::abs(d));
    }
  const double mse = squared / (3.0 * double(a.pixels.size()));
  return {mse == 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse), worst};
}

void bench(const std::string& name, const node::RenderVolume& volume, node::Backend& cpu,
           node::Backend& whole, node::Backend& perRay, const Options& o) {
  const auto& info = volume.info();
  node::Orbit orbit;  // 3/4 view
  const auto camera = node::orbitCamera(orbit, node::boundingRadius(info));
  const auto tf = node::TransferFunction::preset("ct-soft").rescaled(info.valueMin, info.valueMax);
  for (bool shading : {false, true}) {
    node::RenderSettings s;
    s.shading = shading;
    const auto plan = node::planFrame(volume, camera, o.width, o.height, tf, s);
    const Timed c = timeFrames(cpu, volume, plan, o);
    const Timed g = timeFrames(whole, volume, plan, o);
    const Timed r = timeFrames(perRay, volume, plan, o);
    const auto [psnr, worst] = compare(c.image, g.image);
    const auto [psnrPerRay, worstPerRay] = compare(c.image, r.image);
    const auto rate = [](const Timed& t) { return double(t.samples) / (t.medianMs * 1e6); };
    std::printf(
        "| %s | %s | %.1f | %.2f | %.1f | %.2f | %.2f | %.1f | %.2f | %.2f | %.2f | %.1f / %d | "
        "%.1f / %d |\n",
        name.c_str(), shading ? "shaded" : "plain", double(g.samples) / 1e6, c.medianMs, g.firstMs,
        g.medianMs, r.medianMs, c.medianMs / g.medianMs, rate(c), rate(g), rate(r), psnr, worst,
        psnrPerRay, worstPerRay);
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  std::string reason;
  if (!node::cudaAvailable(&reason)) {
    std::fprintf(stderr, "voxwall_bench_cuda: %s\n", reason.c_str());
    return 2;
  }
  try {
    auto cpu = node::makeCpuBackend(o.cpuThreads);
    auto whole = node::makeCudaBackend(node::DeviceDecode::Whole);
    auto perRay = node::makeCudaBackend(node::DeviceDecode::PerRay);
    std::printf(
        "%s against %s, %dx%d, ct-soft, 3/4 view; times: median of %d frames after the "
        "first (which uploads; with --device-decode whole it also decodes on the host)\n\n",
        whole->name().c_str(), cpu->name().c_str(), o.width, o.height, o.frames);
    std::printf(
        "| volume | shading | Msamples | CPU ms | CUDA first ms | CUDA ms | CUDA per-ray ms "
        "| CPU / CUDA | CPU Gsamples/s | CUDA Gsamples/s | per-ray Gsamples/s | CUDA vs "
        "CPU: PSNR dB / max diff | per-ray vs CPU |\n");
    std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int n : o.phantoms) {
      const auto volume = node::RenderVolume::fromVolume(codec::generateSheppLogan(n));
      bench("phantom " + std::to_string(n) + "^3 uint8 raw", volume, *cpu, *whole, *perRay, o);
    }
    for (const std::string& file : o.files) {
      const auto volume = node::RenderVolume::open(file);
      const auto slash = file.find_last_of('/');
      bench(slash == std::string::npos ? file : file.substr(slash + 1), volume, *cpu, *whole,
            *perRay, o);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "voxwall_bench_cuda: %s\n", e.what());
    return 1;
  }
  return 0;
}
