#include <cstdio>
#include <filesystem>
#include <memory>
#include <voxwall/codec/container.hpp>
#include <voxwall/master/default_data.hpp>
#include <voxwall/master/frame_loop.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct RenderOptions {
  std::string input, size = "1920x1080", tf = "mri", tfRange, camera = "30,20,2.6", out = "frames";
  std::string backend = "cpu", background = "black", format = "png", tiles = "1x1";
  double fov = 30, orbitDeg = 0, step = 0.25;
  int frames = 1, threads = 0;
  bool shading = false, noSkip = false, noWrite = false, quiet = false;
  RawInputOptions raw;
};

std::optional<glm::dvec3> parseBackground(const std::string& text) {
  if (text == "none" || text == "transparent") return std::nullopt;
  if (text == "black") return glm::dvec3(0.0);
  if (text == "white") return glm::dvec3(1.0);
  const auto v = parseNumbers(text, "--background");
  if (v.size() != 3 || v[0] < 0 || v[0] > 1 || v[1] < 0 || v[1] > 1 || v[2] < 0 || v[2] > 1)
    throw std::invalid_argument("--background: expected none, black, white or R,G,B in [0, 1]");
  return glm::dvec3(v[0], v[1], v[2]);
}

node::TransferFunction loadTransferFunction(const RenderOptions& o, const codec::VolumeInfo& info) {
  const bool file = o.tf.ends_with(".json") || std::filesystem::exists(o.tf);
  node::TransferFunction tf =
      file ? node::TransferFunction::fromParaViewJson(o.tf) : node::TransferFunction::preset(o.tf);
  for (auto& w : tf.warnings) std::fprintf(stderr, "voxwall: %s: %s\n", o.tf.c_str(), w.c_str());
  if (!o.tfRange.empty()) {
    const auto r = parseNumbers(o.tfRange, "--tf-range");
    if (r.size() != 2 || !(r[1] > r[0]))
      throw std::invalid_argument("--tf-range: expected LO,HI with LO < HI");
    return tf.rescaled(r[0], r[1]);
  }
  // Built-in presets are defined on [0, 1]: stretch them over the data. Files are in data values.
  return file ? tf
              : tf.rescaled(info.valueMin,
                            info.valueMax > info.valueMin ? info.valueMax : info.valueMin + 1);
}

void runRender(const RenderOptions& o) {
  master::SequenceSettings seq;
  std::tie(seq.width, seq.height) = parseSize(o.size, "--size");
  std::tie(seq.tilesX, seq.tilesY) = parseSize(o.tiles, "--tiles");
  const auto cam = parseNumbers(o.camera, "--camera");
  if (cam.size() < 2 || cam.size() > 3)
    throw std::invalid_argument("--camera: expected AZIMUTH,ELEVATION[,DISTANCE]");
  seq.orbit.azimuthDeg = cam[0];
  seq.orbit.elevationDeg = cam[1];
  if (cam.size() == 3) seq.orbit.distance = cam[2];
  if (!(seq.orbit.distance > 0)) throw std::invalid_argument("--camera: distance must be positive");
  if (!(o.fov > 0 && o.fov < 180)) throw std::invalid_argument("--fov must be in (0, 180) degrees");
  seq.orbit.fovYDeg = o.fov;
  if (o.frames < 1) throw std::invalid_argument("--frames must be at least 1");
  seq.frames = o.frames;
  seq.orbitStepDeg = o.orbitDeg != 0 ? o.orbitDeg : 360.0 / o.frames;
  seq.outDir = o.noWrite ? "" : o.out;
  if (o.format != "png" && o.format != "exr")
    throw std::invalid_argument("--format: expected png or exr");
  seq.format = o.format;
  seq.background = parseBackground(o.background);
  if (!(o.step > 0 && o.step <= 8)) throw std::invalid_argument("--step must be in (0, 8] voxels");

  node::RenderSettings render;
  render.stepVoxels = o.step;
  render.shading = o.shading;
  render.emptySpaceSkipping = !o.noSkip;

  std::string input = o.input;
  if (input.empty()) {
    input = master::defaultVolumeSpec();
    if (!o.quiet) std::fprintf(stderr, "voxwall: no volume given, rendering %s\n", input.c_str());
  }
  const auto layout = o.raw.layout();
  node::RenderVolume volume = [&] {
    if (layout || !codec::isContainerFile(input)) {
      codec::Volume v = loadVolume(input, layout);
      if (!o.raw.spacing.empty()) v.spacing = parseSpacing(o.raw.spacing, "--spacing");
      return node::RenderVolume::fromVolume(v);
    }
    return node::RenderVolume::open(input);
  }();
  const auto tf = loadTransferFunction(o, volume.info());
  if (o.backend != "cpu" && o.backend != "cuda")
    throw std::invalid_argument("--backend: expected cpu or cuda");
  auto backend = node::makeBackend(
      o.backend == "cuda" ? node::BackendKind::Cuda : node::BackendKind::Cpu, o.threads);
  const auto& info = volume.info();
  if (!o.quiet)
    std::fprintf(stderr, "voxwall: %s: %dx%dx%d %s (%s), %dx%d, %d frame(s), %s\n", input.c_str(),
                 info.dims.x, info.dims.y, info.dims.z,
                 std::string(codec::scalarName(info.type)).c_str(),
                 std::string(codec::codecName(info.codec)).c_str(), seq.width, seq.height,
                 seq.frames, backend->name().c_str());
  double total = 0;
  std::uint64_t samples = 0;
  master::renderSequence(*backend, volume, tf, render, seq, [&](const master::FrameReport& r) {
    total += r.renderSeconds;
    samples += r.samples;
    if (!o.quiet)
      std::printf("frame %d/%d: render %.1f ms, %.1f Msamples/s%s%s\n", r.frame + 1, seq.frames,
                  r.renderSeconds * 1e3, double(r.samples) / r.renderSeconds / 1e6,
                  r.path.empty() ? "" : " -> ", r.path.c_str());
    std::fflush(stdout);
  });
  if (!o.quiet)
    std::printf("total: %d frame(s), mean render %.1f ms/frame, %.1f Msamples/s\n", seq.frames,
                total / seq.frames * 1e3, double(samples) / total / 1e6);
}

}  // namespace

void addRenderCommand(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand(
      "render",
      "Raycast a volume into image files, orbiting the camera around it (single rank for now)");
  cmd->add_option("input", o->input,
                  "A .vwz file or any volume input (.nii/.nii.gz, .nrrd/.nhdr, .raw with --dims, "
                  ".tif, a slice directory, generated:KIND:SIZE). Default: the MRI template from "
                  "Debian's mricron-data if installed, else a generated Shepp-Logan phantom");
  cmd->add_option("--size", o->size, "Virtual screen size in pixels, WIDTHxHEIGHT")
      ->capture_default_str();
  cmd->add_option("--tiles", o->tiles,
                  "Render the screen as a grid of COLSxROWS tiles (same pixels as one tile)")
      ->capture_default_str();
  cmd->add_option("--tf", o->tf,
                  "Transfer function: a built-in preset (mri, grey, ct-bone, ct-soft, hot, "
                  "cool-warm; stretched over the data range) or a ParaView preset .json (RGBPoints "
                  "and Points in data values)")
      ->capture_default_str();
  cmd->add_option("--tf-range", o->tfRange, "Stretch the transfer function over data values LO,HI");
  cmd->add_option("--camera", o->camera,
                  "Orbit camera of frame 0: AZIMUTH,ELEVATION[,DISTANCE] in degrees around +z and "
                  "multiples of the volume's bounding radius")
      ->capture_default_str();
  cmd->add_option("--fov", o->fov, "Vertical field of view in degrees")->capture_default_str();
  cmd->add_option("--frames", o->frames, "Number of frames")->capture_default_str();
  cmd->add_option("--orbit-deg", o->orbitDeg,
                  "Azimuth step per frame in degrees (default: one full turn over --frames)");
  cmd->add_option("--step", o->step, "Ray step in voxels (of the smallest spacing)")
      ->capture_default_str();
  cmd->add_flag("--shading", o->shading, "Blinn-Phong shading from central-difference gradients");
  cmd->add_flag("--no-skip", o->noSkip, "Disable empty-space skipping (for measurements)");
  cmd->add_option("--backend", o->backend, "cpu or cuda")->capture_default_str();
  cmd->add_option("--threads", o->threads, "CPU backend threads (0 = all cores)")
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Directory for frame_NNNNN.<format> files")
      ->capture_default_str();
  cmd->add_option("--format", o->format,
                  "Frame file format: png (8-bit) or exr (half float, keeps alpha)")
      ->capture_default_str();
  cmd->add_option("--background", o->background,
                  "Composite onto black, white, R,G,B in [0,1], or none (straight alpha in files)")
      ->capture_default_str();
  cmd->add_flag("--no-write", o->noWrite, "Render without writing frames (for timing)");
  cmd->add_flag("-q,--quiet", o->quiet, "Print nothing but errors");
  o->raw.addTo(*cmd);
  cmd->callback([o] { runRender(*o); });
}

}  // namespace voxwall::cli
