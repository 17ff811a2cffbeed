#include "render_settings.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/node/camera.hpp>
#include <voxwall/node/transfer_function.hpp>
#include <voxwall/walls/wall.hpp>

namespace voxwall::cli {

std::optional<glm::dvec3> parseBackground(const std::string& text) {
  if (text == "none" || text == "transparent") return std::nullopt;
  if (text == "black") return glm::dvec3(0.0);
  if (text == "white") return glm::dvec3(1.0);
  const auto v = parseNumbers(text, "--background");
  if (v.size() != 3 || v[0] < 0 || v[0] > 1 || v[1] < 0 || v[1] > 1 || v[2] < 0 || v[2] > 1)
    throw std::invalid_argument("--background: expected none, black, white or R,G,B in [0, 1]");
  return glm::dvec3(v[0], v[1], v[2]);
}

TransferSettings transferSettings(const RenderOptions& o) {
  TransferSettings t;
  t.map = o.tf;
  t.opacity = o.opacity;
  if (!o.tfRange.empty()) {
    const auto r = parseNumbers(o.tfRange, "--tf-range");
    if (r.size() != 2 || !(r[1] > r[0]))
      throw std::invalid_argument("--tf-range: expected LO,HI with LO < HI");
    t.range = std::pair{r[0], r[1]};
  }
  if (!o.window.empty()) {
    const auto w = parseNumbers(o.window, "--window");
    if (w.size() != 2 || !(w[1] > 0))
      throw std::invalid_argument("--window: expected CENTER,WIDTH with WIDTH > 0");
    t.range = std::pair{w[0] - w[1] / 2, w[0] + w[1] / 2};
  }
  if (!o.rescale.empty()) {
    const auto r = parseNumbers(o.rescale, "--rescale");
    if (r.size() != 2 || !(r[0] > 0))
      throw std::invalid_argument("--rescale: expected SLOPE,INTERCEPT with SLOPE > 0");
    t.slope = r[0], t.intercept = r[1];
  }
  t.perStep = choose<bool>(o.range, "--range", {{"series", false}, {"per-step", true}});
  return t;
}

BackendSettings backendSettings(const RenderOptions& o) {
  BackendSettings b;
  b.kind = choose<node::BackendKind>(
      o.backend, "--backend", {{"cpu", node::BackendKind::Cpu}, {"cuda", node::BackendKind::Cuda}});
  b.threads = inRange(o.threads, 0, 4096, "--threads");
  b.simd = choose<bool>(o.simd, "--simd", {{"on", true}, {"off", false}});
  b.decodeCacheBytes = parseBytesOrOff(o.decodeCache, "--decode-cache");
  b.deviceDecode = choose<node::DeviceDecode>(
      o.deviceDecode, "--device-decode",
      {{"whole", node::DeviceDecode::Whole}, {"per-ray", node::DeviceDecode::PerRay}});
  if (!o.memoryBudget.empty()) b.memoryBudgetBytes = parseBytes(o.memoryBudget, "--memory-budget");
  return b;
}

// Memory a rank needs: the mapped volume, its pixels (8 bytes each: the RGBA8 picture and its
// encoded copy, a report to rank 0 or tiles to the sink), its cost grid, and on rank 0 the cost
// grids of every rank's report and, when frames are written (--out), the assembled frame, the
// pixels of the reports and the writer's float copy. Written frames: a rank holds all its pixels,
// which under a dynamic cut may be nearly the whole screen. Otherwise (streaming to a sink) a
// rank holds one band of a rectangle at a time (master::bands), and rank 0 gathers no pixels.
std::uint64_t estimateRankBytes(const master::JobSettings& job, int rank, int ranks,
                                std::uint64_t volumeBytes, std::uint64_t baseBytes) {
  const auto rects = master::firstFrameRects(job, ranks);
  const auto& mine = rects[std::size_t(rank)];
  const std::uint64_t screen = std::uint64_t(job.width) * std::uint64_t(job.height);
  const bool dynamic = job.balance == master::Balance::Dynamic;
  std::uint64_t pixels = 0;
  if (!job.outDir.empty()) {
    if (dynamic && !mine.empty())
      pixels = screen;
    else
      for (const auto& r : mine) pixels += std::uint64_t(r.area());
  } else {
    const auto rows = std::uint64_t(master::bandRows(job));
    if (dynamic && !mine.empty())
      pixels = std::min(screen, std::uint64_t(job.width) * rows);
    else
      for (const auto& r : mine)
        pixels = std::max(pixels, std::min(std::uint64_t(r.area()), std::uint64_t(r.width) * rows));
  }
  const std::uint64_t cells =
      std::uint64_t((job.width + job.balancer.cellPixels - 1) / job.balancer.cellPixels) *
      std::uint64_t((job.height + job.balancer.cellPixels - 1) / job.balancer.cellPixels);
  std::uint64_t bytes = baseBytes + volumeBytes + pixels * 8 + cells * 16 + (1u << 20);
  if (rank == 0) {
    bytes += std::uint64_t(ranks) * cells * 16;
    if (!job.outDir.empty()) bytes += screen * (4 + 4 + 16 + 8);
  }
  return bytes;
}

std::string rectText(const voxwall::Rect& r) {
  return std::to_string(r.width) + "x" + std::to_string(r.height) + "+" + std::to_string(r.x) +
         "+" + std::to_string(r.y);
}

std::string rectList(const std::vector<voxwall::Rect>& rects) {
  std::string list;
  for (const auto& rect : rects) {
    list += ' ';
    list += rectText(rect);
  }
  return list;
}

namespace {

// --wall or --size: the virtual screen.
std::optional<walls::Wall> screen(const RenderOptions& o, master::JobSettings& job) {
  std::optional<walls::Wall> wall;
  if (!o.wall.empty()) {
    if (o.sizeGiven)
      throw std::invalid_argument("--size and --wall both set the screen: give one of them");
    wall = walls::loadWall(o.wall, o.surface);
    job.width = wall->width, job.height = wall->height;
  } else {
    if (o.surface != 0) throw std::invalid_argument("--surface needs --wall");
    std::tie(job.width, job.height) = parseSize(o.size, "--size");
  }
  if (job.width > 65536 || job.height > 65536)
    throw std::invalid_argument("--size: at most 65536 pixels per side");
  return wall;
}

// --sink and how tiles travel to it.
std::optional<master::StreamSettings> streamSettings(const RenderOptions& o,
                                                     const std::optional<walls::Wall>& wall) {
  if (o.sink.empty()) {
    if (!o.token.empty()) throw std::invalid_argument("--token goes with --sink");
    return std::nullopt;
  }
  if (!wall) throw std::invalid_argument("--sink needs --wall: the same wall file the sink shows");
  master::StreamSettings st;
  std::tie(st.host, st.port) = net::parseEndpoint(o.sink, "--sink");
  st.token = o.token;
  st.wallId = wall->id;
  for (const auto& d : wall->displays) st.displays.push_back(d.rect);
  if (!(o.sinkDeadline > 0) || !std::isfinite(o.sinkDeadline))
    throw std::invalid_argument("--sink-deadline must be a positive number of seconds");
  st.deadlineSeconds = o.sinkDeadline;
  st.background = wall->background;
  st.codec.codec = choose<net::TileCodec>(o.tileCodec, "--tile-codec",
                                          {{"jpeg", net::TileCodec::Jpeg},
                                           {"raw", net::TileCodec::Raw},
                                           {"deflate", net::TileCodec::Deflate}});
  st.codec.jpegQuality = inRange(o.jpegQuality, 1, 100, "--jpeg-quality");
  st.codec.subsampling = choose<net::Subsampling>(o.subsampling, "--subsampling",
                                                  {{"444", net::Subsampling::S444},
                                                   {"422", net::Subsampling::S422},
                                                   {"420", net::Subsampling::S420}});
  return st;
}

// --camera, --fov, --pan, --path and --frames: the camera of every frame.
master::CameraPath cameraPath(const RenderOptions& o) {
  const auto cam = parseNumbers(o.camera, "--camera");
  if (cam.size() < 2 || cam.size() > 3)
    throw std::invalid_argument("--camera: expected AZIMUTH,ELEVATION[,DISTANCE]");
  node::Orbit orbit;
  orbit.azimuthDeg = cam[0];
  orbit.elevationDeg = cam[1];
  if (cam.size() == 3) orbit.distance = cam[2];
  if (!o.view.empty()) {
    const auto view = node::anatomicalView(o.view);
    if (!view)
      throw std::invalid_argument("--view: '" + o.view + "' is not one of " +
                                  node::anatomicalViewNames());
    orbit.azimuthDeg = view->azimuthDeg, orbit.elevationDeg = view->elevationDeg;
  }
  if (!(orbit.distance > 0)) throw std::invalid_argument("--camera: distance must be positive");
  if (!(o.fov > 0 && o.fov < 180)) throw std::invalid_argument("--fov must be in (0, 180) degrees");
  orbit.fovYDeg = o.fov;
  if (!o.pan.empty()) {
    const auto pan = parseNumbers(o.pan, "--pan");
    if (pan.size() != 2) throw std::invalid_argument("--pan: expected X,Y in bounding radii");
    orbit.panX = pan[0], orbit.panY = pan[1];
  }
  if (o.frames < 1) throw std::invalid_argument("--frames must be at least 1");
  if (o.path == "orbit")
    return master::CameraPath::orbit(orbit, o.orbitDeg != 0 ? o.orbitDeg : 360.0 / o.frames);
  if (o.path == "still") return master::CameraPath::orbit(orbit, 0.0);
  if (o.path == "orbit-zoom") {
    const int orbitFrames = std::max(1, o.frames / 2);
    return master::CameraPath::orbitThenZoom(orbit, orbitFrames, o.frames - orbitFrames, o.zoomTo);
  }
  return master::CameraPath::fromJsonFile(o.path);
}

// --balance, --tiles, --master-only, --watchdog, --cost-cell: how the screen is cut.
void cutSettings(const RenderOptions& o, master::JobSettings& job) {
  if (o.balance != "static" && o.balance != "dynamic")
    throw std::invalid_argument("--balance: expected static or dynamic");
  job.balance = o.balance == "static" ? master::Balance::Static : master::Balance::Dynamic;
  if (o.tiles != "1x1") {
    if (o.balanceGiven && job.balance == master::Balance::Dynamic)
      throw std::invalid_argument(
          "--tiles cuts the screen statically: it cannot go with --balance dynamic");
    job.balance = master::Balance::Static;
    std::tie(job.staticTilesX, job.staticTilesY) = parseSize(o.tiles, "--tiles");
  }
  job.masterRenders = !o.masterOnly;
  job.watchdogMs = int(inRange(o.watchdogSeconds, 1.0, 86400.0, "--watchdog", "seconds") * 1000);
  job.balancer.cellPixels = inRange(o.costCell, 4, 1024, "--cost-cell", "pixels");
}

}  // namespace

master::JobSettings jobSettings(const RenderOptions& o) {
  master::JobSettings job;
  const auto wall = screen(o, job);
  job.stream = streamSettings(o, wall);
  job.path = cameraPath(o);
  job.frames = o.frames;
  // Streaming to a sink writes no frames on rank 0 unless --out asks for them too.
  job.outDir = o.noWrite || (job.stream && !o.outGiven) ? "" : o.out;
  if (o.format != "png" && o.format != "exr")
    throw std::invalid_argument("--format: expected png or exr");
  job.format = o.format;
  job.background = parseBackground(o.background);
  job.resume = o.resume;
  if (o.resume && o.noWrite)
    throw std::invalid_argument("--resume needs frames on disk, not --no-write");
  cutSettings(o, job);
  job.interactiveStep = inRange(o.interactiveStep, 1, net::kMaxStep, "--interactive-step");
  job.settleSeconds = inRange(o.settle, 0.0, 3600.0, "--settle", "seconds");
  job.refine = master::parseRefineSteps(o.refine);
  const double frameBudget =
      inRange(o.frameBudgetMs, 0.0, 600000.0, "--frame-budget", "milliseconds");
  // A step chosen on the command line is kept: the budget then only applies when given too.
  job.frameBudgetMs = o.interactiveStepGiven && !o.frameBudgetGiven ? 0 : frameBudget;
  return job;
}

master::TimeSettings timeSettings(const RenderOptions& o, int steps) {
  master::TimeSettings time;
  time.rate = inRange(o.timeRate, 0.0, 1000.0, "--time-rate", "steps a second");
  const std::string spec = o.time.empty() && o.timeRate > 0 ? "all" : o.time;
  if (spec.empty()) return time;  // step 0 in every frame
  if (spec == "all") {
    time.last = steps - 1;
  } else {
    std::vector<int> parts;
    std::size_t at = 0;
    for (;;) {
      const std::size_t colon = spec.find(':', at);
      const std::string part = spec.substr(at, colon == std::string::npos ? colon : colon - at);
      std::size_t used = 0;
      int value = -1;
      try {
        value = std::stoi(part, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != part.size() || value < 0)
        throw std::invalid_argument("--time: expected FIRST:LAST[:STRIDE], a step, or all; not '" +
                                    spec + "'");
      parts.push_back(value);
      if (colon == std::string::npos) break;
      at = colon + 1;
    }
    if (parts.size() > 3)
      throw std::invalid_argument("--time: expected FIRST:LAST[:STRIDE], a step, or all");
    time.first = parts[0];
    time.last = parts.size() > 1 ? parts[1] : parts[0];
    time.stride = parts.size() > 2 ? parts[2] : 1;
    if (time.stride < 1) throw std::invalid_argument("--time: the stride must be at least 1");
    if (time.last < time.first)
      throw std::invalid_argument("--time: the last step comes before the first");
  }
  if (time.last >= steps)
    throw std::invalid_argument("--time " + spec + ": the volume has " + std::to_string(steps) +
                                " step(s), 0 to " + std::to_string(steps - 1));
  time.last = time.first + (time.last - time.first) / time.stride * time.stride;
  return time;
}

codec::CodecOptionValues codecRenderOptions(const RenderOptions& o) {
  codec::CodecOptionValues values;
  for (const auto& [flag, value] : o.codecFlags) values.set(flag, value);
  return values;
}

// --lattice and --exact: the ray lattice's side in pixels (0: picked per frame).
int latticeStride(const RenderOptions& o) {
  if (o.exact) {
    if (o.lattice != "auto" && o.lattice != "1")
      throw std::invalid_argument("--exact casts a ray a pixel: it takes no --lattice " +
                                  o.lattice);
    return 1;
  }
  if (o.lattice == "auto") return 0;
  for (int s = 1; s <= node::kMaxLatticeStride; s *= 2)
    if (o.lattice == std::to_string(s)) return s;
  throw std::invalid_argument("--lattice: expected auto or a power of two up to " +
                              std::to_string(node::kMaxLatticeStride) + ", not '" + o.lattice +
                              "'");
}

node::RenderSettings renderSettings(const RenderOptions& o) {
  node::RenderSettings render;
  const bool autoStep = o.step == "auto" && !o.exact;
  if (o.step != "auto") {
    double step = 0;
    try {
      std::size_t used = 0;
      step = std::stod(o.step, &used);
      if (used != o.step.size()) step = 0;
    } catch (const std::exception&) {
    }
    if (!(step > 0 && step <= 8))
      throw std::invalid_argument("--step: expected auto or a step in (0, 8] voxels, not '" +
                                  o.step + "'");
    render.stepVoxels = step;
  }
  const double budget = inRange(o.errorBudget, 20.0, 90.0, "--error-budget", "dB");
  render.errorBudgetDb = autoStep ? budget : 0.0;
  render.shading = o.shading;
  render.cellGradients =
      choose<bool>(o.gradients, "--gradients", {{"cell", true}, {"samples", false}});
  render.emptySpaceSkipping = !o.noSkip;
  render.nearest =
      choose<bool>(o.sampling, "--sampling", {{"trilinear", false}, {"nearest", true}});
  render.levelOfDetail = o.lod;
  render.lodUnderPressure = o.lodUnderPressure;
  render.latticeStride = latticeStride(o);
  render.refineAboveLevels = inRange(o.refineAbove, 0, 255, "--refine-above", "levels");
  if (o.integration != "auto" && o.integration != "pre" && o.integration != "point")
    throw std::invalid_argument("--integration: expected auto, pre or point");
  if (o.exact && o.integration == "pre")
    throw std::invalid_argument(
        "--exact samples the transfer function at points: it takes no "
        "--integration pre");
  render.preIntegrate = o.integration == "pre";
  render.marchIntegration = o.integration == "auto" && autoStep ? node::MarchIntegration::Either
                            : render.preIntegrate               ? node::MarchIntegration::Pre
                                                                : node::MarchIntegration::Point;
  return render;
}

namespace {

// The volume, the screen, and streaming to a wall sink.
void addScreenOptions(CLI::App& cmd, RenderOptions& o, RenderOptionHandles& h) {
  cmd.add_option("input", o.input,
                 "A .vwz file or any volume input (.nii/.nii.gz, .nrrd/.nhdr, .raw with --dims, "
                 ".tif, a slice directory, generated:KIND:SIZE). Default: the MRI template from "
                 "Debian's mricron-data if installed, else a generated Shepp-Logan phantom");
  h.size = cmd.add_option("--size", o.size, "Virtual screen size in pixels, WIDTHxHEIGHT")
               ->capture_default_str();
  cmd.add_option("--wall", o.wall,
                 "Render the virtual screen of this wall (walls/*.json or a Tide configuration; "
                 "bezel gaps included) instead of --size");
  cmd.add_option("--surface", o.surface,
                 "Which surface of a Tide configuration with several to render (0: the first; "
                 "--dry-run lists them)")
      ->capture_default_str();
  cmd.add_option("--sink", o.sink,
                 "Stream every rank's tiles to the wall sink at HOST:PORT (voxwall sink); needs "
                 "--wall. Frames are then written by rank 0 only if --out is given too");
  cmd.add_option("--token", o.token, "Token the sink asks for");
  cmd.add_option("--sink-deadline", o.sinkDeadline,
                 "Seconds the job goes on while no frame's tiles reach the sink (it is down, "
                 "restarting, or its port is full) before it fails; a job that ends without one "
                 "frame having reached the sink fails too")
      ->capture_default_str();
  cmd.add_option("--tile-codec", o.tileCodec,
                 "How tiles travel to the sink: jpeg, raw (exact) or deflate (exact, zlib)")
      ->capture_default_str();
  cmd.add_option("--jpeg-quality", o.jpegQuality, "JPEG quality of streamed tiles, 1-100")
      ->capture_default_str();
  cmd.add_option("--subsampling", o.subsampling, "JPEG chroma subsampling: 444, 422 or 420")
      ->capture_default_str();
  h.interactiveStep =
      cmd.add_option("--interactive-step", o.interactiveStep,
                     "While camera commands from the wall keep arriving, render at 1/N per side "
                     "(the sink upsamples) instead of the step --frame-budget picks; 1: always "
                     "full resolution. Only when streaming without --out")
          ->capture_default_str();
  cmd.add_option("--settle", o.settle,
                 "Seconds without a camera command after which the picture refines (--refine)")
      ->capture_default_str();
  cmd.add_option("--refine", o.refine,
                 "Once the camera settled, frames at these steps, coarse to full resolution, each "
                 "shown as it completes (steps no coarser than the last frame shown are "
                 "skipped); a camera command during a refining or full frame abandons it and "
                 "steering starts again")
      ->capture_default_str();
  h.frameBudget =
      cmd.add_option("--frame-budget", o.frameBudgetMs,
                     "Milliseconds a steered frame should take: the step while steering is picked "
                     "from a probe of the view before the first frame (the screen at 1/16 a side) "
                     "and then from the measured cost of recent frames; 0: off (--interactive-step "
                     "alone). Off when --interactive-step is given without it")
          ->capture_default_str();
}

// How the screen is cut among the ranks, and the job's limits.
void addCutOptions(CLI::App& cmd, RenderOptions& o, RenderOptionHandles& h) {
  cmd.add_option("--tiles", o.tiles,
                 "Static cut: a grid of COLSxROWS tiles dealt to the ranks in turn (implies "
                 "--balance static)")
      ->capture_default_str();
  h.balance = cmd.add_option("--balance", o.balance,
                             "How the screen is cut among the ranks: static (equal strips, "
                             "or --tiles) or dynamic (re-cut every frame from the measured "
                             "costs of the last one)")
                  ->capture_default_str();
  cmd.add_flag("--master-only", o.masterOnly,
               "Rank 0 only assembles and writes frames; the other ranks render");
  cmd.add_flag("--dry-run", o.dryRun,
               "Load the volume on every rank, print the rank -> tile map, each rank's host and "
               "the memory it needs (with the decoded pages its rays reach in the first frame, "
               "rendered at a quarter of its size to count them), then exit");
  cmd.add_option("--memory-budget", o.memoryBudget,
                 "Refuse to start when a rank would need more memory than this (e.g. 2G, 512M)");
  cmd.add_option("--watchdog", o.watchdogSeconds,
                 "Seconds any rank waits for another before the job is ended with a message "
                 "naming it (grows to 4x the slowest frame)")
      ->capture_default_str();
  cmd.add_option("--cost-cell", o.costCell,
                 "Cell size in pixels of the cost grid the dynamic balancer measures")
      ->capture_default_str();
}

// The camera path and the frames.
void addCameraOptions(CLI::App& cmd, RenderOptions& o, RenderOptionHandles& h) {
  cmd.add_option(
         "--path", o.path,
         "Camera path: orbit (one turn over --frames, or --orbit-deg per frame), still (the "
         "--camera of frame 0 throughout: it moves only when steered from the wall), "
         "orbit-zoom (a turn in half the frames, then a zoom to --zoom-to), or a key-frame "
         "JSON file ({\"keyframes\": [{\"frame\": 0, \"azimuth\": 30, \"elevation\": "
         "20, \"distance\": 2.6, \"fov\": 30, \"pan_x\": 0, \"pan_y\": 0}, ...]})")
      ->capture_default_str();
  cmd.add_option("--zoom-to", o.zoomTo, "orbit-zoom: final camera distance in bounding radii")
      ->capture_default_str();
  auto* camera =
      cmd.add_option("--camera", o.camera,
                     "Orbit camera of frame 0: AZIMUTH,ELEVATION[,DISTANCE] in degrees around the "
                     "patient's superior axis from its left (azimuth -90 looks at the face) and "
                     "multiples of the volume's bounding radius")
          ->capture_default_str();
  cmd.add_option("--view", o.view,
                 "Start from an anatomical view instead of --camera (at its default distance): "
                 "anterior (patient's left on the picture's right), posterior, left, "
                 "right, superior, inferior (from the feet, anterior up, as radiologists read "
                 "axial slices)")
      ->excludes(camera);
  cmd.add_option("--pan", o.pan,
                 "Slide the camera across the view by X,Y bounding radii (the volume moves the "
                 "other way on the screen)");
  cmd.add_option("--fov", o.fov, "Vertical field of view in degrees")->capture_default_str();
  h.frames = cmd.add_option("--frames", o.frames,
                            "Number of frames (with --time: one a step unless given)")
                 ->capture_default_str();
  cmd.add_option(
         "--time", o.time,
         "Time steps of a series (.vwz of several steps) the frames show: FIRST:LAST[:STRIDE] "
         "(frame f shows step FIRST + f*STRIDE; with more --frames than steps each step "
         "shows for several frames), one step, or all. Default: step 0")
      ->capture_default_str();
  cmd.add_option("--time-rate", o.timeRate,
                 "On the wall (--sink): play the --time steps (default all) at this many steps a "
                 "second, looping; the wall's page pauses, steps and moves them")
      ->capture_default_str();
  cmd.add_option("--range", o.range,
                 "What a series' transfer function spans: series (every step's values: a step "
                 "does not flicker brighter) or per-step (each step's own values)")
      ->capture_default_str();
  cmd.add_option("--orbit-deg", o.orbitDeg,
                 "Azimuth step per frame in degrees (default: one full turn over --frames)");
}

// Transfer function, sampling and the backend.
void addLookOptions(CLI::App& cmd, RenderOptions& o) {
  cmd.add_option("--tf", o.tf,
                 "Transfer function: a built-in preset stretched over the data range (mri, grey, "
                 "ct-bone, ct-soft, hot, cool-warm), a built-in preset on Hounsfield units for CT "
                 "(hu-bone, hu-soft-tissue, hu-lung, hu-angio, hu-skin: applied as they are, "
                 "whatever the data's range), a ParaView preset or transfer-function .json, or "
                 "FILE:NAME for one map of a file with several (`voxwall tf list FILE` names "
                 "them). Presets on [0,1] or [-1,1] are stretched over the data range as ParaView "
                 "does; other files are in data values")
      ->capture_default_str();
  cmd.add_option("--opacity", o.opacity,
                 "Take the opacity curve from this preset or file (FILE, FILE:NAME) and the "
                 "colours from --tf");
  cmd.add_option("--tf-range", o.tfRange, "Stretch the transfer function over data values LO,HI");
  cmd.add_option("--window", o.window,
                 "Window as radiologists set it, CENTER,WIDTH (level/width, e.g. 400,1800 for "
                 "bone, 40,400 for soft tissue): the transfer function is stretched over "
                 "CENTER-WIDTH/2 .. CENTER+WIDTH/2 (not with --tf-range)")
      ->excludes("--tf-range");
  cmd.add_option("--rescale", o.rescale,
                 "SLOPE,INTERCEPT: the volume's stored values v are SLOPE*v+INTERCEPT in the units "
                 "of the transfer function, --tf-range and --window (e.g. 1,-1024 for a CT stored "
                 "with an offset, so hu-* presets meet Hounsfield units). DICOM series are "
                 "rescaled when read and need none");
  cmd.add_flag("--shading", o.shading, "Blinn-Phong shading from central-difference gradients");
  cmd.add_option("--gradients", o.gradients,
                 "How --shading takes its gradients: cell (central differences at the corners of "
                 "each voxel cell, read once per cell and blended per sample) or samples (six "
                 "extra trilinear samples per sample, the slower original; for comparison). Both "
                 "give the same gradient to rounding; coarser --lod levels and --sampling nearest "
                 "always use samples")
      ->capture_default_str();
}

// The march along the ray and the rays' lattice, sampling and levels.
void addMarchOptions(CLI::App& cmd, RenderOptions& o) {
  cmd.add_option("--step", o.step,
                 "Ray step in voxels (of the smallest spacing), or auto: the longest step (1, "
                 "3/4, 1/2 or 3/8 voxel, each at points and then pre-integrated; else 1/4) whose "
                 "picture of the job's first view, rendered on a probe screen of about 96,000 "
                 "pixels, is --error-budget plus 3 dB from a converged render (1/8-voxel step). "
                 "--exact takes 1/4")
      ->capture_default_str();
  cmd.add_option("--error-budget", o.errorBudget,
                 "With --step auto: the PSNR (dB, 8-bit channels) against a converged render a "
                 "frame is to keep; the tiles' JPEG at quality 90 costs about 55 dB")
      ->capture_default_str();
  cmd.add_option("--lattice", o.lattice,
                 "Rays on a lattice of this many pixels a side where the screen magnifies the "
                 "volume, refined where neighbouring rays differ (--refine-above) and "
                 "interpolated elsewhere: auto (half the pixels a voxel spans at the volume's "
                 "farthest corner, rounded down to a power of two up to 16; 1 where a voxel "
                 "spans under 4 pixels), 1 (a ray a pixel), 2, 4, 8 or 16. CPU backend; CUDA "
                 "casts a ray a pixel")
      ->capture_default_str();
  cmd.add_option("--refine-above", o.refineAbove,
                 "A lattice cell whose corner rays differ by more than this many 8-bit levels in "
                 "any channel is split, down to a ray a pixel")
      ->capture_default_str();
  cmd.add_option("--integration", o.integration,
                 "How a step composites: pre (the segment between two samples, from "
                 "pre-integrated tables: no thin peak of the transfer function is stepped over), "
                 "point (the transfer function at one sample), or auto (with --step auto, "
                 "whichever meets the budget at the longer step; else point)")
      ->capture_default_str();
  cmd.add_flag("--exact", o.exact,
               "A ray a pixel at the --step given (else 1/4 voxel), the transfer function at "
               "points: no lattice, no error budget (for comparisons and references)");
  cmd.add_flag("--no-skip", o.noSkip, "Disable empty-space skipping (for measurements)");
  const std::string levels =
      "Volumes with mip levels (" + codec::RegisteredCodecs::traversalCodecNames() + ")";
  cmd.add_option("--sampling", o.sampling,
                 levels + ": trilinear, or nearest (the discrete voxels of the SVMM thesis)")
      ->capture_default_str();
  cmd.add_flag("--lod", o.lod,
               levels +
                   ": sample coarser levels where a voxel is smaller than the pixel's "
                   "footprint");
  cmd.add_flag(
      "--lod-under-pressure", o.lodUnderPressure,
      levels +
          ", CPU backend with decoded pages: when --decode-cache is full, a sample whose page is "
          "not resident reads level 1 (from "
          "pages of its own, in a quarter of --decode-cache more) instead of evicting a page "
          "mid-frame; those pages are decoded after the frame (a quarter of the cache at "
          "most), so later frames sharpen. render -v counts the samples taken from coarser "
          "levels");
  addCodecFlags(cmd, &codec::Codec::renderOptions, o.codecFlags);
}

// The backend: CPU or CUDA, threads, packets, decoded pages.
void addBackendOptions(CLI::App& cmd, RenderOptions& o) {
  cmd.add_option("--backend", o.backend, "cpu or cuda")->capture_default_str();
  cmd.add_option("--device-decode", o.deviceDecode,
                 "CUDA backend, compressed volume: whole decodes it once on the host and uploads "
                 "raw bricks where they fit in the device's free memory (raw speed on the device; "
                 "host memory about 1.2x the voxels); per-ray uploads the compressed bytes and "
                 "decodes blocks per ray (device memory: the compressed size). A time series, "
                 "--lod, --sampling nearest and --progressive are always per ray")
      ->capture_default_str();
  cmd.add_option("--threads", o.threads,
                 "CPU backend threads per rank (0 = the host's cores shared by its ranks)")
      ->capture_default_str();
  cmd.add_option("--simd", o.simd,
                 "CPU backend: on traces SIMD packets of rays (AVX2 or AVX-512, whichever the CPU "
                 "has), off one ray at a time (the same picture, slower; for comparison)")
      ->capture_default_str();
  cmd.add_option(
         "--decode-cache", o.decodeCache,
         "CPU backend with --simd on: memory per rank for decoded pages of a compressed volume "
         "(the data's own scalar type), decoded as rays first reach them, so frames "
         "after the first render at about the speed of raw data; when full, pages no ray has "
         "touched lately are evicted (the same picture whatever the size; render -v counts "
         "hits, misses and evictions). off: no pages, bricks decoded per ray")
      ->capture_default_str();
}

// Frame files and what is printed.
void addOutputOptions(CLI::App& cmd, RenderOptions& o, RenderOptionHandles& h) {
  cmd.add_flag("--resume", o.resume,
               "Skip frames already complete in --out (made with the same settings)");
  h.out = cmd.add_option("--out", o.out, "Directory for frame_NNNNN.<format> files")
              ->capture_default_str();
  cmd.add_option("--format", o.format,
                 "Frame file format: png (8-bit) or exr (half float, keeps alpha)")
      ->capture_default_str();
  cmd.add_option("--background", o.background,
                 "Composite onto black, white, R,G,B in [0,1], or none (straight alpha in files)")
      ->capture_default_str();
  cmd.add_flag("--no-write", o.noWrite, "Render without writing frames (for timing)");
  cmd.add_flag("-q,--quiet", o.quiet, "Print nothing but errors");
  cmd.add_flag("-v,--verbose", o.verbose,
               "Print how long rank 0 took to open the volume, every frame's rectangles, samples "
               "and rays per rank, each rank's memory "
               "(private, mapped files) and, for a compressed volume, its decoded pages (hits, "
               "decoded on the rays and ahead of them, evicted, samples that waited)");
}

}  // namespace

RenderOptionHandles addRenderOptions(CLI::App& cmd, RenderOptions& o) {
  RenderOptionHandles h;
  addScreenOptions(cmd, o, h);
  addCutOptions(cmd, o, h);
  addCameraOptions(cmd, o, h);
  addLookOptions(cmd, o);
  addMarchOptions(cmd, o);
  addBackendOptions(cmd, o);
  addOutputOptions(cmd, o, h);
  o.raw.addTo(cmd);
  return h;
}

}  // namespace voxwall::cli
