#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <thread>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/core/parallel.hpp>
#include <voxwall/core/process.hpp>
#include <voxwall/core/text.hpp>
#include <voxwall/master/default_data.hpp>
#include <voxwall/master/host_tables.hpp>
#include <voxwall/master/mpi_communicator.hpp>
#include <voxwall/master/render_job.hpp>
#include <voxwall/walls/wall.hpp>

#include "commands.hpp"
#include "render_settings.hpp"

// `voxwall render`: collective setup (every rank loads the volume and agrees on errors), the
// check that every rank holds the same volume, the dry run, the job, and the report. What the
// options mean is in render_settings.cpp.

namespace voxwall::cli {
namespace {

// --tf (and --opacity) put on the data as ParaView applies a preset. `notes` gets what was
// approximated and, for files, how the map met the data: said once, after setup succeeded.
node::TransferFunction loadTransferFunction(const TransferSettings& t,
                                            const codec::VolumeInfo& info,
                                            std::vector<std::string>& notes) {
  const auto& range = t.range;
  const double slope = t.slope, intercept = t.intercept;
  const double lo = info.valueMin * slope + intercept, hi = info.valueMax * slope + intercept;
  node::TransferFunction tf = node::TransferFunction::load(t.map);
  const std::string placed = tf.placeOnData(lo, hi, range);
  if (!t.opacity.empty()) {
    // The opacity curve of another map, put on the data by the same rule.
    node::TransferFunction other = node::TransferFunction::load(t.opacity);
    if (!other.ownOpacity)
      throw std::invalid_argument("--opacity " + t.opacity + ": it has no opacity 'Points'");
    const std::string otherPlaced = other.placeOnData(lo, hi, range);
    tf.takeOpacityFrom(other);
    notes = tf.warnings;
    notes.push_back("opacity from " + otherPlaced);
  } else {
    notes = tf.warnings;
  }
  // Built-in presets need no note on their range; files get one.
  if (!node::TransferFunction::splitSpec(t.map).file.empty()) notes.push_back(placed);
  if (tf.hounsfield && !range && (lo > -500 || hi < 0))
    notes.push_back(formatLine(
        "'%s' is on Hounsfield units, but this volume's values %g..%g reach no air (about -1000) "
        "or no tissue: if it is a CT stored with an offset, give --rescale SLOPE,INTERCEPT (often "
        "1,-1024)",
        t.map.c_str(), lo, hi));
  // From the map's units back to stored values: x -> (x - intercept) / slope.
  if (slope != 1 || intercept != 0)
    tf = tf.rescaled((tf.domainMin() - intercept) / slope, (tf.domainMax() - intercept) / slope);
  return tf;
}

struct Setup {
  master::JobSettings job;
  node::RenderSettings render;
  BackendSettings backendSettings;
  TransferSettings transfer;
  std::optional<node::RenderVolume> volume;
  std::optional<node::TransferFunction> tf;
  std::unique_ptr<node::Backend> backend;
  std::string input;
  std::uint64_t needBytes = 0;
  std::uint64_t pageBytes = 0;       // of needBytes: this rank's decoded pages at most
  double openSeconds = 0;            // the volume's open: its file mapped, its value ranges made
  std::vector<std::string> tfNotes;  // said by rank 0 once setup succeeded
};

node::RenderVolume loadRenderVolume(const RenderOptions& o, const std::string& input) {
  const auto layout = o.raw.layout();
  if (!layout && codec::isContainerFile(input))
    return node::RenderVolume::open(input, std::nullopt, codecRenderOptions(o));
  node::RenderVolume::refuseRenderOptions(codecRenderOptions(o), input);
  codec::Volume v = loadVolume(input, o.raw.readOptions());
  o.raw.applyOverrides(v);
  return node::RenderVolume::fromVolume(v);
}

// The rank's backend; CPU threads default to the host's cores shared by its ranks, but never
// more than this rank may run on.
std::unique_ptr<node::Backend> rankBackend(const BackendSettings& b, master::Communicator& comm,
                                           bool quiet) {
  int threads = b.threads;
  if (threads == 0) {
    const int share = std::max(1, int(std::thread::hardware_concurrency()) / comm.ranksOnHost());
    threads = std::min(share, voxwall::usableCores());
    if (threads < share && !quiet)
      std::fprintf(stderr,
                   "voxwall: rank %d is bound to %d core(s) by its launcher while %d are its "
                   "share; mpirun --bind-to none lets it use them\n",
                   comm.rank(), threads, share);
  }
  if (b.kind == node::BackendKind::Cuda)
    return node::makeBackend(node::BackendKind::Cuda, threads, b.deviceDecode);
  return node::makeCpuBackend(threads, b.simd, b.decodeCacheBytes);
}

// The decoded pages this rank's rays reach in the first frame: its first-frame rectangles rendered
// at a quarter of the resolution per side (pages are 32 voxels wide, so the fewer rays still
// reach nearly every page the full frame's do) by a CPU backend with no page budget: the bytes of
// the pages it decodes and of the bricks they share (zfp's memo).
std::uint64_t firstFramePageBytes(const Setup& s, master::Communicator& comm) {
  const auto rects = master::firstFrameRects(s.job, comm.size())[std::size_t(comm.rank())];
  if (rects.empty()) return 0;
  constexpr int kReduce = 4;
  const int width = std::max(1, s.job.width / kReduce),
            height = std::max(1, s.job.height / kReduce);
  const node::Camera camera =
      node::orbitCamera(s.job.path.at(0), node::boundingRadius(s.volume->info()));
  const node::FramePlan plan = node::planFrame(*s.volume, camera, width, height, *s.tf, s.render);
  const auto backend = node::makeCpuBackend(1, true, std::numeric_limits<std::uint64_t>::max() / 2);
  for (const voxwall::Rect& r : rects) {
    const int x0 = r.x / kReduce, y0 = r.y / kReduce;
    const int x1 = std::min(width, (r.x + r.width + kReduce - 1) / kReduce);
    const int y1 = std::min(height, (r.y + r.height + kReduce - 1) / kReduce);
    if (x1 <= x0 || y1 <= y0) continue;
    voxwall::Image out;
    (void)backend->render(*s.volume, plan, voxwall::Rect{x0, y0, x1 - x0, y1 - y0}, out);
  }
  // The pages decoded (none evicted with this budget) and, for zfp, the bricks they share.
  return node::cpuDecodeCacheUse(*backend).bytes;
}

// --time, --time-rate and --range on the volume's steps: which step each frame shows (one frame a
// step unless --frames is given), and for --range per-step a transfer function for each step.
void applyTime(const RenderOptions& o, bool quiet, Setup& s) {
  const int steps = s.volume->steps();
  if (o.timeRate > 0 && !s.job.stream)
    throw std::invalid_argument(
        "--time-rate plays a series on the wall (--sink); a batch job shows a step a frame "
        "(--time)");
  const master::TimeSettings time = timeSettings(o, steps);
  if (!o.time.empty() && !o.framesGiven && o.timeRate == 0) {
    RenderOptions each = o;
    each.frames = time.count();
    s.job = jobSettings(each);
  }
  s.job.time = time;
  if (steps > 1 && o.time.empty() && o.timeRate == 0 && !quiet)
    std::fprintf(stderr,
                 "voxwall: %s holds %d time steps; rendering step 0 (--time FIRST:LAST or --time "
                 "all shows others)\n",
                 s.input.c_str(), steps);
  if (s.transfer.perStep) {
    std::vector<std::string> notes;
    for (int k = 0; k < steps; ++k) {
      codec::VolumeInfo info = s.volume->info();
      std::tie(info.valueMin, info.valueMax) = s.volume->stepRange(k);
      s.job.stepTransferFunctions.push_back(loadTransferFunction(s.transfer, info, notes));
    }
  }
}

// Everything a rank does before the job; throws what is wrong on this rank.
void setUpRank(const RenderOptions& o, master::Communicator& comm, bool quiet, Setup& s) {
  s.job = jobSettings(o);
  s.render = renderSettings(o);
  s.backendSettings = backendSettings(o);
  s.transfer = transferSettings(o);
  const auto baseBytes = processMemory().residentBytes;
  s.input = o.input;
  if (s.input.empty()) {
    s.input = master::defaultVolumeSpec();
    if (!quiet) std::fprintf(stderr, "voxwall: no volume given, rendering %s\n", s.input.c_str());
  }
  const auto opening = std::chrono::steady_clock::now();
  s.volume = loadRenderVolume(o, s.input);
  s.openSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - opening).count();
  if ((s.render.nearest || s.render.levelOfDetail || s.render.lodUnderPressure) &&
      !s.volume->traversal())
    throw std::invalid_argument(
        "--sampling nearest, --lod and --lod-under-pressure need a volume with mip levels "
        "(compress it with --codec " +
        codec::RegisteredCodecs::traversalCodecNames() + ")");
  s.tf = loadTransferFunction(s.transfer, s.volume->info(), s.tfNotes);
  applyTime(o, quiet, s);
  // A CPU rank with packets may decode pages of a brick-coded volume, up to --decode-cache. A dry
  // run counts the pages this rank's rays reach in the first frame.
  const BackendSettings& b = s.backendSettings;
  std::uint64_t pages =
      b.decodesPages() ? node::cpuDecodeCacheNeed(*s.volume, b.decodeCacheBytes) : 0;
  // Under pressure, level 1's pages come on top once the budget is full (a dry run: once the
  // first frame's pages are over it).
  const std::uint64_t coarse = pages > 0 && s.render.lodUnderPressure
                                   ? node::cpuCoarsePageNeed(*s.volume, b.decodeCacheBytes)
                                   : 0;
  if (o.dryRun && pages > 0) {
    const std::uint64_t first = firstFramePageBytes(s, comm);
    pages = std::min(pages, first) + (first > pages ? coarse : 0);
  } else {
    pages += coarse;
  }
  s.pageBytes = pages;
  // Loading may have peaked higher than the job will run (a codec holds the file's bytes and the
  // volume it builds from them at once): this rank's measured peak so far counts too.
  const auto loadPeakBytes = processMemory().peakBytes;
  s.needBytes =
      std::max(loadPeakBytes, estimateRankBytes(s.job, comm.rank(), comm.size(),
                                                s.volume->storedBytes() + pages, baseBytes));
  if (b.memoryBudgetBytes) {
    const auto budget = *b.memoryBudgetBytes;
    if (s.needBytes > budget)
      throw std::runtime_error("needs " + humanBytes(double(s.needBytes)) + " (volume " +
                               humanBytes(double(s.volume->storedBytes())) +
                               (pages ? ", decoded pages " + humanBytes(double(pages)) : "") +
                               " plus frame buffers), over the --memory-budget of " +
                               humanBytes(double(budget)));
  }
  if (!o.dryRun) s.backend = rankBackend(b, comm, quiet);
}

// --step auto: the march picked from the error budget on the job's first view. Every rank picks
// it alike (the probe's picture does not depend on its threads), so no word need pass.
void pickMarch(Setup& s, bool quiet) {
  if (s.render.errorBudgetDb <= 0 || !s.backend) return;
  const node::Camera camera =
      node::orbitCamera(s.job.path.at(0), node::boundingRadius(s.volume->info()));
  const node::MarchChoice choice =
      node::chooseMarch(*s.backend, *s.volume, camera, s.job.width, s.job.height, *s.tf, s.render,
                        s.render.errorBudgetDb);
  s.render.stepVoxels = choice.stepVoxels;
  s.render.preIntegrate = choice.preIntegrate;
  if (!quiet)
    std::fprintf(stderr,
                 "voxwall: step %g voxels%s for the %g dB error budget (the first view on a "
                 "%dx%d probe: %.1f dB; %d marches tried in %.2f s)\n",
                 choice.stepVoxels, choice.preIntegrate ? ", pre-integrated" : "",
                 s.render.errorBudgetDb, choice.probeWidth, choice.probeHeight, choice.probePsnrDb,
                 choice.marchesTried, choice.seconds);
}

// Ends the job on an error every rank has agreed on: rank 0 writes its one line, then every rank
// fails silently. The other ranks wait for rank 0's word that the line is written: a rank that
// exited first with a non-zero status would have the launcher kill rank 0 before it wrote it.
[[noreturn]] void failTogether(master::Communicator& comm, const std::string& verdict,
                               int timeoutMs) {
  if (comm.rank() == 0) {
    std::fprintf(stderr, "voxwall: %s\n", verdict.c_str());
    std::fflush(stderr);
  }
  try {
    master::broadcastString(comm, "written", timeoutMs);
  } catch (const std::exception&) {
    // Rank 0 is gone: nothing more can be said.
  }
  throw SilentFailure();
}

// Setup errors are agreed on by all ranks before anyone goes on (docs/architecture.md): rank 0
// reports the first, the others fail silently.
void setUpTogether(const RenderOptions& o, master::Communicator& comm, bool quiet, Setup& s) {
  const int timeoutMs = int(std::max(1.0, o.watchdogSeconds) * 1000);
  std::string error;
  std::exception_ptr setupError;
  try {
    setUpRank(o, comm, quiet, s);
  } catch (const node::CudaError& e) {
    error = std::string("cuda: ") + e.what();
    setupError = std::current_exception();
  } catch (const std::exception& e) {
    error = e.what();
    setupError = std::current_exception();
  }
  error = master::agreeOnErrors(comm, error, timeoutMs);
  if (error.empty()) return;
  if (comm.size() == 1 && setupError) std::rethrow_exception(setupError);
  failTogether(comm, error, timeoutMs);
}

struct RankHosts {
  std::vector<std::string> hosts;
  std::vector<std::uint64_t> needs;
  std::vector<std::uint64_t> pages;   // of needs: decoded pages
  std::vector<std::uint64_t> mapped;  // of needs: the mapped file
};

// Every rank must hold the same volume, or the tiles would not fit together. Returns every
// rank's host and memory need.
RankHosts checkSameVolume(master::Communicator& comm, const Setup& s, std::uint64_t fingerprint,
                          int timeoutMs) {
  char mine[360];  // fingerprint, need, pages, mapped and a host name of up to 199 characters
  const std::uint64_t mapped = s.volume->mapsFile() ? s.volume->storedBytes() : 0;
  std::snprintf(mine, sizeof mine, "%016llx %llu %llu %llu %s", (unsigned long long)fingerprint,
                (unsigned long long)s.needBytes, (unsigned long long)s.pageBytes,
                (unsigned long long)mapped, comm.hostName().c_str());
  const auto all = master::gatherStrings(comm, mine, timeoutMs);
  std::string verdict;
  RankHosts out;
  for (std::size_t r = 0; r < all.size(); ++r) {
    char hash[32] = {}, host[200] = {};
    unsigned long long need = 0, pages = 0, mappedBytes = 0;
    std::sscanf(all[r].c_str(), "%31s %llu %llu %llu %199s", hash, &need, &pages, &mappedBytes,
                host);
    out.hosts.push_back(host);
    out.needs.push_back(need);
    out.pages.push_back(pages);
    out.mapped.push_back(mappedBytes);
    if (verdict.empty() && std::string(hash) != std::string(all[0].substr(0, 16)))
      verdict = "rank " + std::to_string(r) + " (" + host +
                ") holds a different volume than rank 0 (fingerprint " + hash + " vs " +
                all[0].substr(0, 16) + "): give every rank the same file";
  }
  verdict = master::broadcastString(comm, verdict, timeoutMs);
  if (verdict.empty()) return out;
  failTogether(comm, verdict, timeoutMs);
}

void printDryRun(const RenderOptions& o, master::Communicator& comm, const Setup& s,
                 const RankHosts& ranks) {
  if (!o.wall.empty()) {
    const auto surfaces = walls::loadWalls(o.wall);
    std::printf("wall %s: %zu surface(s)\n", o.wall.c_str(), surfaces.size());
    for (std::size_t n = 0; n < surfaces.size(); ++n)
      std::printf("  %s%s\n", walls::describeSurface(surfaces[n], int(n)).c_str(),
                  int(n) == o.surface ? " (rendered)" : "");
  }
  const auto rects = master::firstFrameRects(s.job, comm.size());
  const bool dynamic = s.job.balance == master::Balance::Dynamic;
  std::printf("dry run: %d rank(s), %s cut%s\n", comm.size(), dynamic ? "dynamic" : "static",
              dynamic ? " (first frame shown; re-cut from measured costs after it)" : "");
  if (s.pageBytes > 0 ||
      std::any_of(ranks.pages.begin(), ranks.pages.end(), [](std::uint64_t p) { return p > 0; }))
    std::printf(
        "decoded pages: those each rank's rays reach in the first frame (rendered at a "
        "quarter of its size to count them), at most --decode-cache %s%s\n",
        o.decodeCache.c_str(),
        s.render.lodUnderPressure ? ", and level 1's where they are more (a quarter of it)" : "");
  for (int r = 0; r < comm.size(); ++r) {
    const std::string list = rectList(rects[std::size_t(r)]);
    const std::uint64_t pages = ranks.pages[std::size_t(r)], need = ranks.needs[std::size_t(r)];
    const std::uint64_t mapped = std::min(need, ranks.mapped[std::size_t(r)]);
    std::printf(
        "rank %d on %s: needs %s (private %s%s, mapped file %s, shared by the ranks on "
        "one host); tiles:%s\n",
        r, ranks.hosts[std::size_t(r)].c_str(), humanBytes(double(need)).c_str(),
        humanBytes(double(need - mapped)).c_str(),
        pages ? (", of it decoded pages " + humanBytes(double(pages))).c_str() : "",
        humanBytes(double(mapped)).c_str(),
        list.empty() ? " none (assembles and writes)" : list.c_str());
  }
}

// The pixels of a frame's rectangles (its reduced screen's, for a steered frame).
unsigned long long framePixels(const master::FrameSummary& f) {
  unsigned long long pixels = 0;
  for (const auto& rects : f.rects)
    for (const auto& r : rects) pixels += (unsigned long long)r.area();
  return pixels;
}

// A rank's resident memory split into its own, its share of what the ranks on its host share
// (decode tables made once for all of them, the MPI library's buffers) and its mapped files'.
std::string memoryText(const master::RankMemory& m) {
  return "private " + humanBytes(double(m.privateBytes)) + ", shared " +
         humanBytes(double(m.sharedBytes)) + " (its share), mapped files " +
         humanBytes(double(m.fileBytes)) + " (shared by the ranks on one host)";
}

// The per-frame lines on rank 0 and the totals at the end.
class Report {
 public:
  Report(const RenderOptions& o, const Setup& s, bool quiet) : o_(o), s_(s), quiet_(quiet) {}

  void frame(const master::FrameSummary& f) {
    ++frames_;
    imbalanceSum_ += f.imbalance;
    totals_.frameSeconds += f.frameSeconds;
    totals_.renderSeconds += f.renderSeconds;
    totals_.gatherSeconds += f.gatherSeconds;
    totals_.assembleSeconds += f.assembleSeconds;
    totals_.writeWaitSeconds += f.writeWaitSeconds;
    totals_.samples += f.samples;
    if (quiet_) return;
    std::string ranks;
    for (std::size_t i = 0; i < f.ranks.size(); ++i) {
      char text[64];
      std::snprintf(text, sizeof text, "%s%d:%.0f", i ? " " : "", f.ranks[i],
                    f.rankSeconds[i] * 1e3);
      ranks += text;
    }
    const std::string timeStep =
        s_.volume->steps() > 1 ? ", time step " + std::to_string(f.timeStep) : std::string();
    std::printf("frame %d/%d%s: %.1f ms, imbalance %.2f, render ms [%s], %.1f Msamples/s%s%s%s\n",
                f.frame + 1, s_.job.frames, timeStep.c_str(), f.frameSeconds * 1e3, f.imbalance,
                ranks.c_str(), double(f.samples) / f.renderSeconds / 1e6, sinkText(f).c_str(),
                f.path.empty() ? "" : " -> ", f.path.c_str());
    if (f.probeSeconds > 0)
      std::printf(
          "  a probe of the view predicts %.2f s a full frame a rank; steered frames keep "
          "to --frame-budget %g ms\n",
          f.probeSeconds, s_.job.frameBudgetMs);
    for (const auto& note : f.sinkNotes) std::printf("  %s\n", note.c_str());
    if (o_.verbose) {
      for (std::size_t i = 0; i < f.ranks.size(); ++i) {
        std::printf("  rank %d:%s\n", f.ranks[i], rectList(f.rects[i]).c_str());
        const master::PageStats& p = f.rankPages[i];
        if (p.hits + p.missed > 0)
          std::printf(
              "    decoded pages: %.2f%% hits (%llu of %llu samples), %llu decoded, %llu "
              "evicted, %s resident%s, %llu samples waited for a page another thread "
              "decoded; %llu pages decoded ahead of the rays\n",
              100.0 * double(p.hits) / double(p.hits + p.missed), (unsigned long long)p.hits,
              (unsigned long long)(p.hits + p.missed), (unsigned long long)p.decoded,
              (unsigned long long)p.evictions, humanBytes(double(p.residentBytes)).c_str(),
              s_.render.lodUnderPressure
                  ? (", " + std::to_string(p.coarse) + " samples from coarser levels").c_str()
                  : "",
              (unsigned long long)p.waited, (unsigned long long)p.ahead);
        if (i < f.rankMemory.size()) std::printf("    %s\n", memoryText(f.rankMemory[i]).c_str());
      }
      std::printf(
          "  %llu samples, %llu rays for %llu pixels (ray lattice %d, refined above %d "
          "levels), step %g voxels%s\n",
          (unsigned long long)f.samples, (unsigned long long)f.rays,
          (unsigned long long)framePixels(f), f.latticeStride, s_.render.refineAboveLevels,
          s_.render.stepVoxels, s_.render.preIntegrate ? ", pre-integrated" : "");
    }
    std::fflush(stdout);
  }

  void totals(const master::JobSummary& summary, const RankHosts& ranks) const {
    if (quiet_) return;
    for (const auto& note : summary.sinkNotes) std::printf("%s\n", note.c_str());
    if (summary.framesSkipped > 0)
      std::printf("resume: %d frame(s) already complete in %s, rendered %d\n",
                  summary.framesSkipped, s_.job.outDir.c_str(), summary.framesRendered);
    if (frames_ > 0) times(summary);
    for (const auto& m : summary.memory)
      std::printf("rank %d on %s: resident %s, peak %s; %s\n", m.rank,
                  ranks.hosts[std::size_t(m.rank)].c_str(),
                  humanBytes(double(m.residentBytes)).c_str(),
                  humanBytes(double(m.peakResidentBytes)).c_str(), memoryText(m).c_str());
  }

 private:
  std::string sinkText(const master::FrameSummary& f) const {
    if (!s_.job.stream) return "";
    char text[512];
    const std::string label = net::stepLabel(f.step, f.phase);
    const std::string step = label.empty() ? label : ", " + label;
    std::snprintf(text, sizeof text, " -> sink: %d/%zu ranks, %.1f KiB, encode %.1f ms%s%s%s%s%s",
                  f.streamedRanks, f.ranks.size(), double(f.streamedBytes) / 1024,
                  f.encodeSeconds * 1e3, step.c_str(),
                  f.controls ? ", camera moved from the wall" : "",
                  f.abandoned ? ", abandoned: the camera moved while it rendered" : "",
                  f.streamError.empty() ? "" : "; ", f.streamError.c_str());
    return text;
  }

  void times(const master::JobSummary& summary) const {
    const double n = frames_;
    std::printf(
        "total: %d frame(s) in %.2f s, %.2f frames/s, mean frame %.1f ms, mean imbalance "
        "%.2f, %.1f Msamples/s\n",
        frames_, summary.seconds, n / summary.seconds, totals_.frameSeconds / n * 1e3,
        imbalanceSum_ / n, double(totals_.samples) / totals_.renderSeconds / 1e6);
    const double whole = totals_.frameSeconds;
    std::printf(
        "frame time on rank 0: render %.0f%%, wait for ranks %.0f%%, assemble %.0f%%, "
        "wait for writer %.0f%%\n",
        100 * (whole - totals_.gatherSeconds - totals_.assembleSeconds - totals_.writeWaitSeconds) /
            whole,
        100 * totals_.gatherSeconds / whole, 100 * totals_.assembleSeconds / whole,
        100 * totals_.writeWaitSeconds / whole);
    if (summary.writeSeconds > 0)
      std::printf(
          "writer (background thread, overlaps the next frame): encode + write %.1f ms/frame\n",
          summary.writeSeconds / n * 1e3);
  }

  const RenderOptions& o_;
  const Setup& s_;
  bool quiet_;
  master::FrameSummary totals_;
  int frames_ = 0;
  double imbalanceSum_ = 0;
};

void runRender(const RenderOptions& o) {
  // Under mpirun every rank runs this; alone, the job is one rank without MPI.
  std::unique_ptr<master::Communicator> comm = master::launchedByMpi()
                                                   ? master::makeMpiCommunicator(nullptr, nullptr)
                                                   : master::makeSingleRankCommunicator();
  const bool quiet = o.quiet || comm->rank() != 0;
  if (comm->size() > 1) {
    // Before any rank opens the volume: tables a codec makes to decode (tvq's associated
    // codebooks) are then made by one rank a host and read by the others.
    const std::string tables =
        master::shareDecodeTablesOnHost(*comm, int(std::max(1.0, o.watchdogSeconds) * 1000));
    if (!quiet && o.verbose) std::fprintf(stderr, "voxwall: %s\n", tables.c_str());
  }
  Setup s;
  setUpTogether(o, *comm, quiet, s);
  const std::uint64_t fingerprint = s.volume->fingerprint();
  // Every byte of the file was read by now; from here a rank holds what its rays read.
  s.volume->releaseMappedPages();
  const RankHosts ranks =
      checkSameVolume(*comm, s, fingerprint, int(std::max(1.0, o.watchdogSeconds) * 1000));
  s.job.manifest = manifest(o, s.job, s.render, fingerprint);
  pickMarch(s, quiet);
  const auto& info = s.volume->info();
  if (!quiet)
    std::fprintf(stderr, "voxwall: %s: %dx%dx%d %s (%s), %dx%d, %d frame(s), %d rank(s), %s\n",
                 s.input.c_str(), info.dims.x, info.dims.y, info.dims.z,
                 std::string(codec::scalarName(info.type)).c_str(),
                 std::string(codec::codecName(info.codec)).c_str(), s.job.width, s.job.height,
                 s.job.frames, comm->size(), o.dryRun ? "dry run" : s.backend->name().c_str());
  if (!quiet && o.verbose)
    std::fprintf(stderr,
                 "voxwall: rank 0 opened %s in %.2f s (read or mapped, value ranges for skipping "
                 "empty space made)\n",
                 s.input.c_str(), s.openSeconds);
  if (!quiet)
    for (const auto& note : s.tfNotes)
      std::fprintf(stderr, "voxwall: %s: %s\n", o.tf.c_str(), note.c_str());
  if (o.dryRun) {
    if (comm->rank() == 0) printDryRun(o, *comm, s, ranks);
    return;
  }
  Report report(o, s, quiet);
  master::JobSummary summary;
  try {
    summary = master::runRenderJob(*comm, *s.backend, *s.volume, *s.tf, s.render, s.job,
                                   [&](const master::FrameSummary& f) { report.frame(f); });
  } catch (const std::exception& e) {
    // After setup a failure on one rank would strand the others: end the whole job.
    if (comm->size() == 1) throw;
    std::fprintf(stderr, "voxwall: rank %d (%s): %s\n", comm->rank(), comm->hostName().c_str(),
                 e.what());
    std::fflush(stderr);
    comm->abort(1);
    throw;  // not reached: abort ends the process
  }
  report.totals(summary, ranks);
}

}  // namespace

void addRenderCommand(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand(
      "render",
      "Raycast a volume into image files. Under mpirun (mpirun -np N voxwall render ...) rank 0 "
      "picks the camera and cuts the screen among the ranks every frame; every rank renders its "
      "part from its own copy of the volume, and rank 0 assembles and writes the frames");
  const RenderOptionHandles handles = addRenderOptions(*cmd, *o);
  cmd->callback([o, handles] {
    handles.noteGiven(*o);
    runRender(*o);
  });
}

}  // namespace voxwall::cli
