#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/parallel.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/master/default_data.hpp>
#include <voxwall/master/mpi_communicator.hpp>
#include <voxwall/master/render_job.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/wall.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct RenderOptions {
  std::string input, size = "1920x1080", tf = "mri", tfRange, camera = "30,20,2.6", out = "frames";
  std::string backend = "cpu", background = "black", format = "png", tiles = "1x1";
  std::string path = "orbit", balance = "dynamic", memoryBudget, pan;
  std::string sink, token, wall, subsampling = "420", tileCodec = "jpeg";
  int jpegQuality = 90;
  bool sizeGiven = false, outGiven = false;
  double fov = 30, orbitDeg = 0, step = 0.25, zoomTo = 1.2, watchdogSeconds = 120;
  int frames = 1, threads = 0, costCell = 32;
  int testStallRank = -1, testStallCall = 0;
  std::string sampling = "trilinear";
  bool lod = false;
  bool shading = false, noSkip = false, noWrite = false, quiet = false, verbose = false;
  bool balanceGiven = false, masterOnly = false, dryRun = false, resume = false;
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

node::TransferFunction loadTransferFunction(const RenderOptions& o, const codec::VolumeInfo& info,
                                            bool quiet) {
  const bool file = o.tf.ends_with(".json") || std::filesystem::exists(o.tf);
  node::TransferFunction tf =
      file ? node::TransferFunction::fromParaViewJson(o.tf) : node::TransferFunction::preset(o.tf);
  if (!quiet)
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

std::uint64_t parseBytes(const std::string& text, const std::string& option) {
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = text.substr(used);
  if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
  if (!unit.empty() && unit.back() == 'i') unit.pop_back();
  const std::string units = "KMGT";
  double scale = 1;
  if (unit.size() == 1 && units.find(char(std::toupper(unit[0]))) != std::string::npos)
    scale = std::pow(1024.0, double(units.find(char(std::toupper(unit[0]))) + 1));
  else if (!unit.empty())
    used = 0;
  if (used == 0 || !(value > 0) || !std::isfinite(value * scale))
    throw std::invalid_argument(option + ": expected a size such as 512M, 2G or 1.5GiB");
  return std::uint64_t(value * scale);
}

// Test hook (hidden option): one rank stops answering at one frame, as a hung rank would.
class StallingBackend final : public node::Backend {
 public:
  StallingBackend(std::unique_ptr<node::Backend> inner, int stallAtCall)
      : inner_(std::move(inner)), stallAtCall_(stallAtCall) {}
  std::string name() const override { return inner_->name(); }

 protected:
  node::TileStats renderTile(const node::RenderVolume& volume, const node::FramePlan& plan,
                             const node::Rect& tile, node::Image& out,
                             node::CostGrid* costs) override {
    if (calls_++ == stallAtCall_)
      for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
    return inner_->render(volume, plan, tile, out, costs);
  }

 private:
  std::unique_ptr<node::Backend> inner_;
  int stallAtCall_, calls_ = 0;
};

// Memory a rank needs: the mapped volume, its frame buffers (the whole screen for a dynamic cut,
// which may give one rank nearly everything), and on rank 0 the assembled frame, the reports it
// receives and the writer's float copy.
std::uint64_t estimateRankBytes(const master::JobSettings& job, int rank, int ranks,
                                std::uint64_t volumeBytes, std::uint64_t baseBytes) {
  const auto rects = master::firstFrameRects(job, ranks);
  std::uint64_t pixels = 0;
  if (job.balance == master::Balance::Dynamic && !rects[std::size_t(rank)].empty())
    pixels = std::uint64_t(job.width) * std::uint64_t(job.height);
  else
    for (const auto& r : rects[std::size_t(rank)]) pixels += std::uint64_t(r.area());
  const std::uint64_t screen = std::uint64_t(job.width) * std::uint64_t(job.height);
  const std::uint64_t cells =
      std::uint64_t((job.width + job.balancer.cellPixels - 1) / job.balancer.cellPixels) *
      std::uint64_t((job.height + job.balancer.cellPixels - 1) / job.balancer.cellPixels);
  std::uint64_t bytes = baseBytes + volumeBytes + pixels * 8 + cells * 16 + (1u << 20);
  if (rank == 0) bytes += screen * (4 + 4 + 16 + 8) + std::uint64_t(ranks) * cells * 16;
  return bytes;
}

std::string rectText(const node::Rect& r) {
  return std::to_string(r.width) + "x" + std::to_string(r.height) + "+" + std::to_string(r.x) +
         "+" + std::to_string(r.y);
}

std::string rectList(const std::vector<node::Rect>& rects) {
  std::string list;
  for (const auto& rect : rects) {
    list += ' ';
    list += rectText(rect);
  }
  return list;
}

struct Setup {
  master::JobSettings job;
  node::RenderSettings render;
  std::optional<node::RenderVolume> volume;
  std::optional<node::TransferFunction> tf;
  std::unique_ptr<node::Backend> backend;
  std::string input;
  std::uint64_t needBytes = 0;
};

master::JobSettings jobSettings(const RenderOptions& o) {
  master::JobSettings job;
  std::optional<walls::Wall> wall;
  if (!o.wall.empty()) {
    if (o.sizeGiven)
      throw std::invalid_argument("--size and --wall both set the screen: give one of them");
    wall = walls::loadWall(o.wall);
    job.width = wall->width, job.height = wall->height;
  } else {
    std::tie(job.width, job.height) = parseSize(o.size, "--size");
  }
  if (job.width > 65536 || job.height > 65536)
    throw std::invalid_argument("--size: at most 65536 pixels per side");
  if (!o.sink.empty()) {
    if (!wall)
      throw std::invalid_argument("--sink needs --wall: the same wall file the sink shows");
    master::StreamSettings st;
    std::tie(st.host, st.port) = net::parseEndpoint(o.sink, "--sink");
    st.token = o.token;
    st.wallId = wall->id;
    st.background = wall->background;
    if (o.tileCodec == "jpeg")
      st.codec.codec = net::TileCodec::Jpeg;
    else if (o.tileCodec == "raw")
      st.codec.codec = net::TileCodec::Raw;
    else if (o.tileCodec == "deflate")
      st.codec.codec = net::TileCodec::Deflate;
    else
      throw std::invalid_argument("--tile-codec: expected jpeg, raw or deflate");
    if (o.jpegQuality < 1 || o.jpegQuality > 100)
      throw std::invalid_argument("--jpeg-quality must be in [1, 100]");
    st.codec.jpegQuality = o.jpegQuality;
    if (o.subsampling == "444")
      st.codec.subsampling = net::Subsampling::S444;
    else if (o.subsampling == "422")
      st.codec.subsampling = net::Subsampling::S422;
    else if (o.subsampling == "420")
      st.codec.subsampling = net::Subsampling::S420;
    else
      throw std::invalid_argument("--subsampling: expected 444, 422 or 420");
    job.stream = st;
  } else if (!o.token.empty()) {
    throw std::invalid_argument("--token goes with --sink");
  }
  const auto cam = parseNumbers(o.camera, "--camera");
  if (cam.size() < 2 || cam.size() > 3)
    throw std::invalid_argument("--camera: expected AZIMUTH,ELEVATION[,DISTANCE]");
  node::Orbit orbit;
  orbit.azimuthDeg = cam[0];
  orbit.elevationDeg = cam[1];
  if (cam.size() == 3) orbit.distance = cam[2];
  if (!(orbit.distance > 0)) throw std::invalid_argument("--camera: distance must be positive");
  if (!(o.fov > 0 && o.fov < 180)) throw std::invalid_argument("--fov must be in (0, 180) degrees");
  orbit.fovYDeg = o.fov;
  if (!o.pan.empty()) {
    const auto pan = parseNumbers(o.pan, "--pan");
    if (pan.size() != 2) throw std::invalid_argument("--pan: expected X,Y in bounding radii");
    orbit.panX = pan[0], orbit.panY = pan[1];
  }
  if (o.frames < 1) throw std::invalid_argument("--frames must be at least 1");
  job.frames = o.frames;
  if (o.path == "orbit") {
    job.path = master::CameraPath::orbit(orbit, o.orbitDeg != 0 ? o.orbitDeg : 360.0 / o.frames);
  } else if (o.path == "orbit-zoom") {
    const int orbitFrames = std::max(1, o.frames / 2);
    job.path =
        master::CameraPath::orbitThenZoom(orbit, orbitFrames, o.frames - orbitFrames, o.zoomTo);
  } else {
    job.path = master::CameraPath::fromJsonFile(o.path);
  }
  // Streaming to a sink writes no frames on rank 0 unless --out asks for them too.
  job.outDir = o.noWrite || (job.stream && !o.outGiven) ? "" : o.out;
  if (o.format != "png" && o.format != "exr")
    throw std::invalid_argument("--format: expected png or exr");
  job.format = o.format;
  job.background = parseBackground(o.background);
  job.resume = o.resume;
  if (o.resume && o.noWrite)
    throw std::invalid_argument("--resume needs frames on disk, not --no-write");
  if (o.balance != "static" && o.balance != "dynamic")
    throw std::invalid_argument("--balance: expected static or dynamic");
  job.balance = o.balance == "static" ? master::Balance::Static : master::Balance::Dynamic;
  if (o.tiles != "1x1") {
    if (o.balanceGiven && job.balance == master::Balance::Dynamic)
      throw std::invalid_argument(
          "--tiles cuts the screen statically: it cannot go with "
          "--balance dynamic");
    job.balance = master::Balance::Static;
    std::tie(job.staticTilesX, job.staticTilesY) = parseSize(o.tiles, "--tiles");
  }
  job.masterRenders = !o.masterOnly;
  if (!(o.watchdogSeconds >= 1 && o.watchdogSeconds <= 86400))
    throw std::invalid_argument("--watchdog must be in [1, 86400] seconds");
  job.watchdogMs = int(o.watchdogSeconds * 1000);
  if (o.costCell < 4 || o.costCell > 1024)
    throw std::invalid_argument("--cost-cell must be in [4, 1024] pixels");
  job.balancer.cellPixels = o.costCell;
  return job;
}

std::string manifest(const RenderOptions& o, const master::JobSettings& job,
                     const node::RenderSettings& render, std::uint64_t fingerprint) {
  char hex[32];
  std::snprintf(hex, sizeof hex, "%016llx", (unsigned long long)fingerprint);
  nlohmann::json m;
  m["voxwall_job"] = 1;
  m["volume_fingerprint"] = hex;
  m["size"] = {job.width, job.height};
  m["wall"] = o.wall;
  m["frames"] = job.frames;
  m["path"] = o.path;
  m["camera"] = o.camera;
  m["fov"] = o.fov;
  m["pan"] = o.pan;
  m["orbit_deg"] = o.orbitDeg;
  m["zoom_to"] = o.zoomTo;
  m["tf"] = o.tf;
  m["tf_range"] = o.tfRange;
  m["step"] = render.stepVoxels;
  m["shading"] = render.shading;
  if (render.nearest) m["sampling"] = "nearest";
  if (render.levelOfDetail) m["lod"] = true;
  m["format"] = job.format;
  m["background"] = o.background;
  m["backend"] = o.backend;  // CUDA and CPU may differ in the last bit of a channel
  // Files named by the settings count by their contents: an edited file is another render.
  for (const auto& [key, file] : {std::pair{"path_file", o.path}, std::pair{"tf_file", o.tf}}) {
    if (!std::filesystem::is_regular_file(file)) continue;
    std::ifstream in(file, std::ios::binary);
    m[key] = std::string(std::istreambuf_iterator<char>(in), {});
  }
  return m.dump();
}

void runRender(const RenderOptions& o) {
  // Under mpirun every rank runs this; alone, the job is one rank without MPI.
  std::unique_ptr<master::Communicator> comm = master::launchedByMpi()
                                                   ? master::makeMpiCommunicator(nullptr, nullptr)
                                                   : master::makeSingleRankCommunicator();
  const bool leader = comm->rank() == 0;
  const bool quiet = o.quiet || !leader;
  const int setupTimeoutMs = int(std::max(1.0, o.watchdogSeconds) * 1000);
  Setup s;
  // Setup errors are agreed on by all ranks before anyone goes on (docs/architecture.md).
  std::string error;
  std::exception_ptr setupError;
  try {
    s.job = jobSettings(o);
    if (!(o.step > 0 && o.step <= 8))
      throw std::invalid_argument("--step must be in (0, 8] voxels");
    s.render.stepVoxels = o.step;
    s.render.shading = o.shading;
    s.render.emptySpaceSkipping = !o.noSkip;
    if (o.sampling != "trilinear" && o.sampling != "nearest")
      throw std::invalid_argument("--sampling: expected trilinear or nearest");
    s.render.nearest = o.sampling == "nearest";
    s.render.levelOfDetail = o.lod;
    if (o.backend != "cpu" && o.backend != "cuda")
      throw std::invalid_argument("--backend: expected cpu or cuda");
    const auto baseBytes = master::processMemory().first;
    s.input = o.input;
    if (s.input.empty()) {
      s.input = master::defaultVolumeSpec();
      if (!quiet) std::fprintf(stderr, "voxwall: no volume given, rendering %s\n", s.input.c_str());
    }
    const auto layout = o.raw.layout();
    if (layout || !codec::isContainerFile(s.input)) {
      codec::Volume v = loadVolume(s.input, layout);
      if (!o.raw.spacing.empty()) v.spacing = parseSpacing(o.raw.spacing, "--spacing");
      s.volume = node::RenderVolume::fromVolume(v);
    } else {
      s.volume = node::RenderVolume::open(s.input);
    }
    if ((s.render.nearest || s.render.levelOfDetail) && !s.volume->traversal()) {
      const std::string names = codec::RegisteredCodecs::traversalCodecNames();
      throw std::invalid_argument(
          "--sampling nearest and --lod need a volume with mip levels "
          "(compress it with --codec " +
          names + ")");
    }
    s.needBytes =
        estimateRankBytes(s.job, comm->rank(), comm->size(), s.volume->storedBytes(), baseBytes);
    if (!o.memoryBudget.empty()) {
      const auto budget = parseBytes(o.memoryBudget, "--memory-budget");
      if (s.needBytes > budget)
        throw std::runtime_error("needs " + humanBytes(double(s.needBytes)) + " (volume " +
                                 humanBytes(double(s.volume->storedBytes())) +
                                 " plus frame buffers), over the --memory-budget of " +
                                 humanBytes(double(budget)));
    }
    s.tf = loadTransferFunction(o, s.volume->info(), quiet);
    if (!o.dryRun) {
      int threads = o.threads;
      if (threads == 0) {
        // The host's cores shared by its ranks, but never more than this rank may run on.
        const int share =
            std::max(1, int(std::thread::hardware_concurrency()) / comm->ranksOnHost());
        threads = std::min(share, codec::usableCores());
        if (threads < share && !quiet)
          std::fprintf(stderr,
                       "voxwall: rank %d is bound to %d core(s) by its launcher while %d are its "
                       "share; mpirun --bind-to none lets it use them\n",
                       comm->rank(), threads, share);
      }
      s.backend = node::makeBackend(
          o.backend == "cuda" ? node::BackendKind::Cuda : node::BackendKind::Cpu, threads);
      if (o.testStallRank == comm->rank())
        s.backend = std::make_unique<StallingBackend>(std::move(s.backend), o.testStallCall);
    }
  } catch (const node::CudaError& e) {
    error = std::string("cuda: ") + e.what();
    setupError = std::current_exception();
  } catch (const std::exception& e) {
    error = e.what();
    setupError = std::current_exception();
  }
  error = master::agreeOnErrors(*comm, error, setupTimeoutMs);
  if (!error.empty()) {
    if (comm->size() == 1 && setupError) std::rethrow_exception(setupError);
    if (!leader) throw SilentFailure();
    throw std::runtime_error(error);
  }

  // Every rank must hold the same volume, or the tiles would not fit together.
  const auto& info = s.volume->info();
  const std::uint64_t fingerprint = s.volume->fingerprint();
  char mine[256];
  std::snprintf(mine, sizeof mine, "%016llx %llu %s", (unsigned long long)fingerprint,
                (unsigned long long)s.needBytes, comm->hostName().c_str());
  const auto all = master::gatherStrings(*comm, mine, setupTimeoutMs);
  std::string verdict;
  std::vector<std::string> hosts;
  std::vector<std::uint64_t> needs;
  for (std::size_t r = 0; r < all.size(); ++r) {
    char hash[32] = {}, host[200] = {};
    unsigned long long need = 0;
    std::sscanf(all[r].c_str(), "%31s %llu %199s", hash, &need, host);
    hosts.push_back(host);
    needs.push_back(need);
    if (verdict.empty() && std::string(hash) != std::string(all[0].substr(0, 16)))
      verdict = "rank " + std::to_string(r) + " (" + host +
                ") holds a different volume than rank "
                "0 (fingerprint " +
                hash + " vs " + all[0].substr(0, 16) + "): give every rank the same file";
  }
  verdict = master::broadcastString(*comm, verdict, setupTimeoutMs);
  if (!verdict.empty()) {
    if (!leader) throw SilentFailure();
    throw std::runtime_error(verdict);
  }
  s.job.manifest = manifest(o, s.job, s.render, fingerprint);

  if (!quiet)
    std::fprintf(stderr, "voxwall: %s: %dx%dx%d %s (%s), %dx%d, %d frame(s), %d rank(s), %s\n",
                 s.input.c_str(), info.dims.x, info.dims.y, info.dims.z,
                 std::string(codec::scalarName(info.type)).c_str(),
                 std::string(codec::codecName(info.codec)).c_str(), s.job.width, s.job.height,
                 s.job.frames, comm->size(), o.dryRun ? "dry run" : s.backend->name().c_str());
  if (o.dryRun) {
    if (leader) {
      const auto rects = master::firstFrameRects(s.job, comm->size());
      std::printf("dry run: %d rank(s), %s cut%s\n", comm->size(),
                  s.job.balance == master::Balance::Dynamic ? "dynamic" : "static",
                  s.job.balance == master::Balance::Dynamic
                      ? " (first frame shown; re-cut from measured costs after it)"
                      : "");
      for (int r = 0; r < comm->size(); ++r) {
        const std::string list = rectList(rects[std::size_t(r)]);
        std::printf("rank %d on %s: needs %s; tiles:%s\n", r, hosts[std::size_t(r)].c_str(),
                    humanBytes(double(needs[std::size_t(r)])).c_str(),
                    list.empty() ? " none (assembles and writes)" : list.c_str());
      }
    }
    return;
  }

  master::FrameSummary totals;
  int frames = 0;
  double imbalanceSum = 0;
  const auto summary = [&] {
    // After setup a failure on one rank would strand the others: end the whole job.
    try {
      return master::runRenderJob(
          *comm, *s.backend, *s.volume, *s.tf, s.render, s.job, [&](const master::FrameSummary& f) {
            ++frames;
            imbalanceSum += f.imbalance;
            totals.frameSeconds += f.frameSeconds;
            totals.renderSeconds += f.renderSeconds;
            totals.gatherSeconds += f.gatherSeconds;
            totals.assembleSeconds += f.assembleSeconds;
            totals.writeWaitSeconds += f.writeWaitSeconds;
            totals.samples += f.samples;
            if (quiet) return;
            std::string ranks;
            for (std::size_t i = 0; i < f.ranks.size(); ++i) {
              char text[64];
              std::snprintf(text, sizeof text, "%s%d:%.0f", i ? " " : "", f.ranks[i],
                            f.rankSeconds[i] * 1e3);
              ranks += text;
            }
            std::string sinkText;
            if (s.job.stream) {
              char text[512];
              std::snprintf(text, sizeof text,
                            " -> sink: %d/%zu ranks, %.1f KiB, encode %.1f ms%s%s%s",
                            f.streamedRanks, f.ranks.size(), double(f.streamedBytes) / 1024,
                            f.encodeSeconds * 1e3, f.controls ? ", camera moved from the wall" : "",
                            f.streamError.empty() ? "" : "; ", f.streamError.c_str());
              sinkText = text;
            }
            std::printf(
                "frame %d/%d: %.1f ms, imbalance %.2f, render ms [%s], %.1f Msamples/s%s%s%s\n",
                f.frame + 1, s.job.frames, f.frameSeconds * 1e3, f.imbalance, ranks.c_str(),
                double(f.samples) / f.renderSeconds / 1e6, sinkText.c_str(),
                f.path.empty() ? "" : " -> ", f.path.c_str());
            for (const auto& note : f.sinkNotes) std::printf("  %s\n", note.c_str());
            if (o.verbose)
              for (std::size_t i = 0; i < f.ranks.size(); ++i)
                std::printf("  rank %d:%s\n", f.ranks[i], rectList(f.rects[i]).c_str());
            std::fflush(stdout);
          });
    } catch (const std::exception& e) {
      if (comm->size() == 1) throw;
      std::fprintf(stderr, "voxwall: rank %d (%s): %s\n", comm->rank(), comm->hostName().c_str(),
                   e.what());
      std::fflush(stderr);
      comm->abort(1);
      throw;  // not reached: abort ends the process
    }
  }();
  if (quiet) return;
  for (const auto& note : summary.sinkNotes) std::printf("%s\n", note.c_str());
  if (summary.framesSkipped > 0)
    std::printf("resume: %d frame(s) already complete in %s, rendered %d\n", summary.framesSkipped,
                s.job.outDir.c_str(), summary.framesRendered);
  if (frames > 0) {
    const double n = frames;
    std::printf(
        "total: %d frame(s) in %.2f s, %.2f frames/s, mean frame %.1f ms, mean imbalance "
        "%.2f, %.1f Msamples/s\n",
        frames, summary.seconds, n / summary.seconds, totals.frameSeconds / n * 1e3,
        imbalanceSum / n, double(totals.samples) / totals.renderSeconds / 1e6);
    const double whole = totals.frameSeconds;
    std::printf(
        "frame time on rank 0: render %.0f%%, wait for ranks %.0f%%, assemble %.0f%%, "
        "wait for writer %.0f%%\n",
        100 * (whole - totals.gatherSeconds - totals.assembleSeconds - totals.writeWaitSeconds) /
            whole,
        100 * totals.gatherSeconds / whole, 100 * totals.assembleSeconds / whole,
        100 * totals.writeWaitSeconds / whole);
    if (summary.writeSeconds > 0)
      std::printf(
          "writer (background thread, overlaps the next frame): encode + write %.1f "
          "ms/frame\n",
          summary.writeSeconds / n * 1e3);
  }
  for (const auto& m : summary.memory)
    std::printf("rank %d on %s: resident %s, peak %s\n", m.rank, hosts[std::size_t(m.rank)].c_str(),
                humanBytes(double(m.residentBytes)).c_str(),
                humanBytes(double(m.peakResidentBytes)).c_str());
}

}  // namespace

void addRenderCommand(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand(
      "render",
      "Raycast a volume into image files. Under mpirun (mpirun -np N voxwall render ...) rank 0 "
      "picks the camera and cuts the screen among the ranks every frame; every rank renders its "
      "part from its own copy of the volume, and rank 0 assembles and writes the frames");
  cmd->add_option("input", o->input,
                  "A .vwz file or any volume input (.nii/.nii.gz, .nrrd/.nhdr, .raw with --dims, "
                  ".tif, a slice directory, generated:KIND:SIZE). Default: the MRI template from "
                  "Debian's mricron-data if installed, else a generated Shepp-Logan phantom");
  auto* size = cmd->add_option("--size", o->size, "Virtual screen size in pixels, WIDTHxHEIGHT")
                   ->capture_default_str();
  cmd->add_option("--wall", o->wall,
                  "Render the virtual screen of this wall (walls/*.json or a Tide configuration; "
                  "bezel gaps included) instead of --size");
  cmd->add_option("--sink", o->sink,
                  "Stream every rank's tiles to the wall sink at HOST:PORT (voxwall sink); needs "
                  "--wall. Frames are then written by rank 0 only if --out is given too");
  cmd->add_option("--token", o->token, "Token the sink asks for");
  cmd->add_option("--tile-codec", o->tileCodec,
                  "How tiles travel to the sink: jpeg, raw (exact) or deflate (exact, zlib)")
      ->capture_default_str();
  cmd->add_option("--jpeg-quality", o->jpegQuality, "JPEG quality of streamed tiles, 1-100")
      ->capture_default_str();
  cmd->add_option("--subsampling", o->subsampling, "JPEG chroma subsampling: 444, 422 or 420")
      ->capture_default_str();
  cmd->add_option("--tiles", o->tiles,
                  "Static cut: a grid of COLSxROWS tiles dealt to the ranks in turn (implies "
                  "--balance static)")
      ->capture_default_str();
  auto* balance = cmd->add_option("--balance", o->balance,
                                  "How the screen is cut among the ranks: static (equal strips, "
                                  "or --tiles) or dynamic (re-cut every frame from the measured "
                                  "costs of the last one)")
                      ->capture_default_str();
  cmd->add_flag("--master-only", o->masterOnly,
                "Rank 0 only assembles and writes frames; the other ranks render");
  cmd->add_flag("--dry-run", o->dryRun,
                "Load the volume on every rank, print the rank -> tile map, each rank's host and "
                "the memory it needs, then exit");
  cmd->add_option("--memory-budget", o->memoryBudget,
                  "Refuse to start when a rank would need more memory than this (e.g. 2G, 512M)");
  cmd->add_option("--watchdog", o->watchdogSeconds,
                  "Seconds any rank waits for another before the job is ended with a message "
                  "naming it (grows to 4x the slowest frame)")
      ->capture_default_str();
  cmd->add_flag("--resume", o->resume,
                "Skip frames already complete in --out (made with the same settings)");
  cmd->add_option(
         "--path", o->path,
         "Camera path: orbit (one turn over --frames, or --orbit-deg per frame), "
         "orbit-zoom (a turn in half the frames, then a zoom to --zoom-to), or a key-frame "
         "JSON file ({\"keyframes\": [{\"frame\": 0, \"azimuth\": 30, \"elevation\": "
         "20, \"distance\": 2.6, \"fov\": 30, \"pan_x\": 0, \"pan_y\": 0}, ...]})")
      ->capture_default_str();
  cmd->add_option("--zoom-to", o->zoomTo, "orbit-zoom: final camera distance in bounding radii")
      ->capture_default_str();
  cmd->add_option("--cost-cell", o->costCell,
                  "Cell size in pixels of the cost grid the dynamic balancer measures")
      ->capture_default_str();
  cmd->add_option("--test-stall-rank", o->testStallRank)->group("");
  cmd->add_option("--test-stall-call", o->testStallCall)->group("");
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
  cmd->add_option("--pan", o->pan,
                  "Slide the camera across the view by X,Y bounding radii (the volume moves the "
                  "other way on the screen)");
  cmd->add_option("--fov", o->fov, "Vertical field of view in degrees")->capture_default_str();
  cmd->add_option("--frames", o->frames, "Number of frames")->capture_default_str();
  cmd->add_option("--orbit-deg", o->orbitDeg,
                  "Azimuth step per frame in degrees (default: one full turn over --frames)");
  cmd->add_option("--step", o->step, "Ray step in voxels (of the smallest spacing)")
      ->capture_default_str();
  cmd->add_flag("--shading", o->shading, "Blinn-Phong shading from central-difference gradients");
  cmd->add_flag("--no-skip", o->noSkip, "Disable empty-space skipping (for measurements)");
  cmd->add_option("--sampling", o->sampling,
                  "svmm volumes: trilinear, or nearest (the discrete voxels of the SVMM thesis)")
      ->capture_default_str();
  cmd->add_flag("--lod", o->lod,
                "svmm volumes: sample coarser mip levels where a voxel is smaller than the "
                "pixel's footprint");
  cmd->add_option("--backend", o->backend, "cpu or cuda")->capture_default_str();
  cmd->add_option("--threads", o->threads,
                  "CPU backend threads per rank (0 = the host's cores shared by its ranks)")
      ->capture_default_str();
  auto* out = cmd->add_option("--out", o->out, "Directory for frame_NNNNN.<format> files")
                  ->capture_default_str();
  cmd->add_option("--format", o->format,
                  "Frame file format: png (8-bit) or exr (half float, keeps alpha)")
      ->capture_default_str();
  cmd->add_option("--background", o->background,
                  "Composite onto black, white, R,G,B in [0,1], or none (straight alpha in files)")
      ->capture_default_str();
  cmd->add_flag("--no-write", o->noWrite, "Render without writing frames (for timing)");
  cmd->add_flag("-q,--quiet", o->quiet, "Print nothing but errors");
  cmd->add_flag("-v,--verbose", o->verbose, "Print every rank's rectangles every frame");
  o->raw.addTo(*cmd);
  cmd->callback([o, balance, size, out] {
    o->balanceGiven = balance->count() > 0;
    o->sizeGiven = size->count() > 0;
    o->outGiven = out->count() > 0;
    runRender(*o);
  });
}

}  // namespace voxwall::cli
