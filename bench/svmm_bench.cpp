// SVMM benchmark: the thesis's parameter grid (Faas 2016, Table 5.1 and
// Fig. 5.2) on the Menger sponge levels 4-5 (RGBA, coloured by a gradient as in the thesis) and
// on a real MRI, and raycast time per 1920x1080 frame for raw against SVMM.
//
//   voxwall_bench_svmm [MRI.nii.gz] [--threads N] [--frames N] [--no-grid] [--no-render]
//
// Prints markdown tables. Ratios are written as the thesis writes them: 100:x means the coded
// data is x % of the uncompressed voxels (4 bytes per RGBA voxel, 1 per uint8 voxel).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/node/renderer.hpp>

using namespace voxwall;

namespace {

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

struct Data {
  std::string name;
  bool rgba = false;
  codec::svmm::RgbaVolume rgbaVolume;
  codec::Volume volume;
  std::size_t voxels() const { return rgba ? rgbaVolume.rgba.size() : volume.voxelCount(); }
  double rawBytes() const { return rgba ? 4.0 * double(voxels()) : double(volume.data.size()); }
};

struct Result {
  double bytes = 0, psnr = 0, seconds = 0;
  int levels = 0;
};

Result encode(const Data& d, const codec::svmm::Params& p) {
  voxwall::Progress quiet;
  codec::svmm::EncodeStats stats;
  const auto start = std::chrono::steady_clock::now();
  const auto c = d.rgba ? codec::svmm::encodeRgba(d.rgbaVolume, p, quiet, &stats)
                        : codec::svmm::encode(d.volume, p, quiet, &stats);
  Result r;
  r.seconds = seconds(start);  // includes the PSNR measurement (a full decode)
  r.bytes = double(c.payloadBytes());
  r.psnr = stats.psnr;
  r.levels = stats.levels;
  return r;
}

std::string psnrText(double p) {
  if (std::isinf(p)) return "lossless";
  char b[32];
  std::snprintf(b, sizeof b, "%.2f", p);
  return b;
}

void grid(const Data& d, int threads) {
  std::printf("\n### %s (%zu voxels, %s)\n\n", d.name.c_str(), d.voxels(),
              d.rgba ? "RGBA32" : "uint8 DENSITY8");
  std::printf(
      "| w | r | q | levels | ratio | bits/voxel | PSNR dB | encode s | ratio, block-compressed "
      "base | bits/voxel | PSNR dB |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  const double bitsRaw = d.rgba ? 32.0 : 8.0;
  auto row = [&](const char* w, int r, int q, const Result& a, const Result& b) {
    std::printf("| %s | %d | %d | %d | 100:%.1f | %.3f | %s | %.2f | 100:%.1f | %.3f | %s |\n", w,
                r, q, a.levels, 100.0 * a.bytes / d.rawBytes(), bitsRaw * a.bytes / d.rawBytes(),
                psnrText(a.psnr).c_str(), a.seconds, 100.0 * b.bytes / d.rawBytes(),
                bitsRaw * b.bytes / d.rawBytes(), psnrText(b.psnr).c_str());
    std::fflush(stdout);
  };
  {
    // The thesis's "SVO" reference: w = 2, r = 2, lossless.
    codec::svmm::Params p;
    p.blockWidth = 2, p.rootWidth = 2, p.quality = 100, p.threads = threads;
    const Result a = encode(d, p);
    p.baseCompression = true;
    row("2 (SVO)", 2, 100, a, encode(d, p));
  }
  for (const char* w : {"4", "8", "stepped"})
    for (int r : {8, 32, 128})
      for (int q : {100, 90, 80, 65}) {
        codec::svmm::Params p;
        p.stepped = std::strcmp(w, "stepped") == 0;
        p.blockWidth = p.stepped ? 4 : std::atoi(w);
        p.rootWidth = r, p.quality = q, p.threads = threads;
        const Result a = encode(d, p);
        p.baseCompression = true;
        row(w, r, q, a, encode(d, p));
      }
}

struct Frame {
  double ms = 0;
  double msamples = 0;
  voxwall::Image image;
};

Frame frameMs(const node::RenderVolume& v, const node::RenderSettings& s, const std::string& tfName,
              int frames, int threads) {
  node::Orbit orbit;
  orbit.azimuthDeg = 30, orbit.elevationDeg = 20;
  const auto camera = node::orbitCamera(orbit, node::boundingRadius(v.info()));
  const auto tf =
      node::TransferFunction::preset(tfName).rescaled(v.info().valueMin, v.info().valueMax);
  const int w = 1920, h = 1080;
  const auto plan = node::planFrame(v, camera, w, h, tf, s);
  auto backend = node::makeCpuBackend(threads);
  voxwall::Image image;
  backend->render(v, plan, {0, 0, w, h}, image);  // warm-up
  std::uint64_t samples = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int f = 0; f < frames; ++f) samples += backend->render(v, plan, {0, 0, w, h}, image).samples;
  Frame out;
  out.ms = 1000.0 * seconds(start) / frames;
  out.msamples = double(samples) / frames / 1e6;
  out.image = std::move(image);
  return out;
}

void renders(const std::string& name, const codec::Volume& volume, const std::string& tf,
             int frames, int threads) {
  std::printf("\n### %s, 1920x1080, %s transfer function, %d thread(s), mean of %d frame(s)\n\n",
              name.c_str(), tf.c_str(), threads, frames);
  std::printf(
      "| volume | bits/voxel | frame ms | shaded frame ms | Msamples/frame | image PSNR vs raw, "
      "shaded | nearest frame ms | LOD frame ms |\n|---|---|---|---|---|---|---|---|\n");
  voxwall::Image reference;
  auto line = [&](const std::string& label, const node::RenderVolume& v, bool svmm) {
    node::RenderSettings plain, shaded, nearest, lod;
    shaded.shading = true;
    nearest.nearest = true;
    lod.levelOfDetail = true;
    const Frame a = frameMs(v, plain, tf, frames, threads);
    const Frame b = frameMs(v, shaded, tf, frames, threads);
    std::string c = "-", d = "-";
    if (svmm) {
      char t[32];
      std::snprintf(t, sizeof t, "%.0f", frameMs(v, nearest, tf, frames, threads).ms);
      c = t;
      std::snprintf(t, sizeof t, "%.0f", frameMs(v, lod, tf, frames, threads).ms);
      d = t;
    }
    std::string psnr = "-";
    if (!svmm) {
      reference = b.image;
    } else {
      char t[32];
      const double p = voxwall::compareImages(reference, b.image).psnrDb;
      if (std::isinf(p))
        std::snprintf(t, sizeof t, "identical");
      else
        std::snprintf(t, sizeof t, "%.2f dB", p);
      psnr = t;
    }
    std::printf("| %s | %.3f | %.0f | %.0f | %.1f | %s | %s | %s |\n", label.c_str(),
                8.0 * double(v.storedBytes()) / double(volume.voxelCount()), a.ms, b.ms, a.msamples,
                psnr.c_str(), c.c_str(), d.c_str());
    std::fflush(stdout);
  };
  line("raw (16^3 bricks)", node::RenderVolume::fromVolume(volume), false);
  struct Config {
    const char* label;
    int w, r, q;
    bool stepped, bc;
  };
  for (const Config& c : {Config{"svmm w=4 r=32 q=100", 4, 32, 100, false, false},
                          Config{"svmm w=8 r=32 q=100", 8, 32, 100, false, false},
                          Config{"svmm stepped r=32 q=100", 0, 32, 100, true, false},
                          Config{"svmm w=4 r=32 q=90", 4, 32, 90, false, false},
                          Config{"svmm w=4 r=32 q=80", 4, 32, 80, false, false},
                          Config{"svmm w=4 r=32 q=90, block-compressed", 4, 32, 90, false, true}}) {
    codec::svmm::Params p;
    p.blockWidth = c.w, p.rootWidth = c.r, p.quality = c.q, p.stepped = c.stepped;
    p.baseCompression = c.bc;
    voxwall::Progress quiet;
    auto compressed = codec::svmm::encode(volume, p, quiet);
    const std::string path = "/tmp/voxwall_bench_svmm.vwz";
    codec::writeContainer(compressed, path);
    line(c.label, node::RenderVolume::open(path), true);
    std::remove(path.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string mri = "/usr/share/mricron/templates/ch2better.nii.gz";
  int threads = 0, frames = 3;
  bool doGrid = true, doRender = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--threads" && i + 1 < argc)
      threads = std::atoi(argv[++i]);
    else if (a == "--frames" && i + 1 < argc)
      frames = std::atoi(argv[++i]);
    else if (a == "--no-grid")
      doGrid = false;
    else if (a == "--no-render")
      doRender = false;
    else if (a == "-h" || a == "--help") {
      std::printf(
          "usage: voxwall_bench_svmm [MRI] [--threads N] [--frames N] [--no-grid] "
          "[--no-render]\n");
      return 0;
    } else
      mri = a;
  }
  try {
    const codec::Volume head = codec::readVolume(mri);
    if (doGrid) {
      std::printf("## SVMM parameter grid\n");
      for (int level : {4, 5}) {
        Data d;
        d.name = "Menger sponge level " + std::to_string(level);
        d.rgba = true;
        d.rgbaVolume = codec::svmm::generateMengerRgba(level);
        grid(d, threads);
      }
      Data d;
      d.name = mri;
      d.volume = head;
      grid(d, threads);
    }
    if (doRender) {
      std::printf("\n## Raycast time per frame, raw against SVMM\n");
      renders(mri, head, "mri", frames, threads == 0 ? 2 : threads);
      codec::Volume menger = codec::generateMenger(5);
      renders("Menger sponge level 5 (uint8)", menger, "grey", frames, threads == 0 ? 2 : threads);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "voxwall_bench_svmm: %s\n", e.what());
    return 1;
  }
  return 0;
}
