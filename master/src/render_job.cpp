#include <algorithm>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <random>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/process.hpp>
#include <voxwall/core/text.hpp>
#include <voxwall/master/frame_messages.hpp>
#include <voxwall/master/render_job.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/net/wire.hpp>
#include <voxwall/node/rank_renderer.hpp>

#include "frame_output.hpp"

namespace voxwall::master {

namespace {

using Clock = std::chrono::steady_clock;

// A job id the sink has not seen: random, never 0.
std::uint64_t newJobId() {
  std::random_device device;
  std::uint64_t id = 0;
  while (id == 0) id = (std::uint64_t(device()) << 32) ^ device();
  return id;
}

std::vector<int> renderingRanks(const JobSettings& job, int ranks) {
  if (!job.masterRenders && ranks < 2)
    throw std::invalid_argument("--master-only needs at least 2 ranks (rank 0 renders nothing)");
  std::vector<int> out;
  for (int r = job.masterRenders ? 0 : 1; r < ranks; ++r) out.push_back(r);
  return out;
}

// The static cut: per rendering slot, its list of rectangles.
std::vector<std::vector<voxwall::Rect>> staticSlots(const JobSettings& job, int slots) {
  std::vector<std::vector<voxwall::Rect>> out(static_cast<std::size_t>(slots));
  if (job.staticTilesX > 0 && job.staticTilesY > 0) {
    const auto tiles = gridCut(job.width, job.height, job.staticTilesX, job.staticTilesY);
    for (std::size_t i = 0; i < tiles.size(); ++i) out[i % std::size_t(slots)].push_back(tiles[i]);
  } else {
    const auto strips = stripCut(job.width, job.height, slots);
    for (std::size_t i = 0; i < strips.size(); ++i) out[i].push_back(strips[i]);
  }
  return out;
}

std::vector<std::vector<voxwall::Rect>> byRank(const std::vector<std::vector<voxwall::Rect>>& slots,
                                               const std::vector<int>& ranks, int size) {
  std::vector<std::vector<voxwall::Rect>> out(static_cast<std::size_t>(size));
  for (std::size_t i = 0; i < ranks.size(); ++i) out[std::size_t(ranks[i])] = slots[i];
  return out;
}

// Asked every few milliseconds, on the thread that makes the collectives (MPI is initialized
// MPI_THREAD_FUNNELED), while a rank renders a frame that may be abandoned: whether it is.
using AbandonWatch = std::function<bool()>;

void setMemory(master::RankReport& report, const ProcessMemory& memory) {
  report.residentBytes = memory.residentBytes, report.peakResidentBytes = memory.peakBytes;
  report.privateBytes = memory.privateBytes, report.fileBytes = memory.fileBytes;
  report.sharedBytes = memory.sharedBytes;
}

master::RankMemory memoryOf(int rank, const master::RankReport& report) {
  return {rank,
          "",
          report.residentBytes,
          report.peakResidentBytes,
          report.privateBytes,
          report.fileBytes,
          report.sharedBytes};
}

// Has this rank's renderer render `rects` of `task`, streams each finished part to the sink (if
// any) and makes this rank's report. A rank whose pixels nobody gathers renders, encodes and sends
// a band at a time (bands()), so it holds one band's pixels however much of the screen the
// balancer gives it. With a `watch`, the frame may be abandoned: the rest is not rendered, and
// the sink is told.
master::RankReport renderRects(int rank, node::RankRenderer& renderer,
                               const node::RenderVolume& volume, const node::TransferFunction& tf,
                               const JobSettings& job, net::TileStreamer* streamer,
                               const master::FrameTask& task,
                               const std::vector<voxwall::Rect>& rects,
                               const AbandonWatch& watch = {}) {
  master::RankReport report;
  report.frame = task.frame;
  report.rank = rank;
  report.pixels = !job.outDir.empty();
  node::RankFrame frame{&volume,
                        &tf,
                        task.camera,
                        task.screenWidth,
                        task.screenHeight,
                        task.cellPixels,
                        rects,
                        report.pixels,
                        bandRows(job),
                        watch,
                        {}};
  const auto before = streamer ? streamer->bytesSent() : 0;
  bool sending = false;
  if (streamer && !rects.empty()) {
    streamer->setJob(task.jobId);
    sending = streamer->beginFrame(task.frame);
    frame.onPart = [&](const voxwall::Rect& part, const voxwall::Image& image,
                       double renderSeconds) {
      if (!sending) return false;
      const auto encodeStart = Clock::now();
      const auto encoded = net::encodeTiles(image, part, job.stream->background, job.stream->codec,
                                            streamer->displayCut(), task.step);
      report.encodeSeconds += since(encodeStart);
      sending = streamer->sendTiles(encoded, task.decidedUnixMicros, task.step,
                                    std::uint32_t(std::min(renderSeconds * 1e6, 4e9)), task.phase);
      return sending;
    };
  }
  auto result = renderer.render(frame);
  report.renderSeconds = result.renderSeconds;
  report.samples = result.samples;
  report.rays = result.rays;
  report.latticeStride = result.latticeStride;
  report.pages = result.pages;
  report.abandoned = result.abandoned;
  report.costs = std::move(result.costs);
  for (auto& tile : result.tiles) report.tiles.push_back({tile.rect, std::move(tile.image)});
  if (streamer && !rects.empty()) {
    report.streamed = sending && streamer->endFrame(report.abandoned);
    report.streamError = streamer->lastError();
    report.streamRefused = !streamer->refused().empty();
    report.streamedBytes = streamer->bytesSent() - before;
  }
  setMemory(report, renderer.memory());
  return report;
}

// The last report, for the stop task: this rank's memory.
master::RankReport finalReport(int rank, const node::RankRenderer& renderer,
                               const master::FrameTask& stop) {
  master::RankReport report;
  report.frame = stop.frame;
  report.rank = rank;
  report.pixels = false;
  setMemory(report, renderer.memory());
  return report;
}

std::unique_ptr<net::TileStreamer> makeStreamer(const JobSettings& job, int rank, int ranks) {
  if (!job.stream) return nullptr;
  net::Hello hello;
  hello.role = net::Role::Renderer;
  hello.rank = rank, hello.rankCount = ranks;
  hello.wallId = job.stream->wallId, hello.token = job.stream->token;
  auto streamer = std::make_unique<net::TileStreamer>(job.stream->host, job.stream->port, hello);
  streamer->expectScreen(job.width, job.height, job.stream->displays);
  if (job.clock) streamer->setClock(job.clock);
  return streamer;
}

}  // namespace

SteeringSettings steeringSettings(const JobSettings& job) {
  SteeringSettings s;
  s.interactive = job.stream.has_value() && job.outDir.empty();
  s.interactiveStep = job.interactiveStep;
  s.refine = job.refine;
  s.settleSeconds = job.settleSeconds;
  s.frameBudgetMs = job.frameBudgetMs;
  return s;
}

namespace {

// The volume and transfer function of each frame's time step: the job's volume, or another step
// of it, opened when a frame first shows it (the step before is let go then).
class StepVolumes {
 public:
  StepVolumes(const node::RenderVolume& volume, const node::TransferFunction& tf,
              const JobSettings& job)
      : volume_(volume), tf_(tf), job_(job) {}

  const node::RenderVolume& volume(const master::FrameTask& task) {
    const int step = int(task.timeStep);
    if (step >= volume_.steps())
      throw FormatError("frame task from rank 0", "asks for time step " + std::to_string(step) +
                                                      " of a volume of " +
                                                      std::to_string(volume_.steps()));
    if (step == volume_.step()) return volume_;
    if (!other_ || other_->step() != step) {
      other_.reset();
      other_.emplace(volume_.atStep(step));
    }
    return *other_;
  }
  const node::TransferFunction& tf(const master::FrameTask& task) const {
    const auto& each = job_.stepTransferFunctions;
    return task.timeStep < each.size() ? each[task.timeStep] : tf_;
  }

 private:
  const node::RenderVolume& volume_;
  const node::TransferFunction& tf_;
  const JobSettings& job_;
  std::optional<node::RenderVolume> other_;
};

// While this rank waits for the next task (and rank 0 for the other ranks), its renderer decodes
// the pages the next frame of the path will sample on this rank's rectangles
// (RankRenderer::decodeAhead); the next render ends it.
void decodeAhead(node::RankRenderer& renderer, StepVolumes& steps, const master::FrameTask& task,
                 const std::vector<voxwall::Rect>& mine, const JobSettings& job) {
  if (!task.ahead || task.stop || mine.empty()) return;
  master::FrameTask next = task;
  next.timeStep = task.aheadTimeStep;
  const node::RankFrame frame{&steps.volume(next),
                              &steps.tf(next),
                              task.aheadCamera,
                              task.screenWidth,
                              task.screenHeight,
                              task.cellPixels,
                              mine,
                              false,
                              bandRows(job),
                              {},
                              {}};
  renderer.decodeAhead(frame);
}

JobSummary runWorker(Communicator& comm, node::Backend& backend, const node::RenderVolume& volume,
                     const node::TransferFunction& tf, const node::RenderSettings& render,
                     const JobSettings& job) {
  JobSummary summary;
  int timeoutMs = job.watchdogMs;
  const auto streamer = makeStreamer(job, comm.rank(), comm.size());
  const auto steering = steeringSettings(job);
  StepVolumes steps(volume, tf, job);
  node::RankRenderer renderer(backend, render);  // ends its pass ahead before `steps` goes
  for (;;) {
    // The next task comes after rank 0 has waited (up to timeoutMs) for the slowest rank: wait
    // twice as long, so that rank 0's watchdog names the culprit before anyone blames rank 0.
    std::vector<std::byte> bytes;
    comm.broadcast(bytes, 2 * timeoutMs);
    const auto task = master::decodeFrameTask(bytes, "frame task from rank 0");
    // The pass ahead reads the step's volume StepVolumes may now let go.
    renderer.endAhead();
    if (task.rects.size() != std::size_t(comm.size()))
      throw FormatError("frame task from rank 0",
                        "has rectangles for " + std::to_string(task.rects.size()) +
                            " ranks in a job of " + std::to_string(comm.size()));
    timeoutMs = int(std::clamp<std::uint32_t>(task.watchdogMs, 1000, 86400000));
    const auto& mine = task.rects[std::size_t(comm.rank())];
    AbandonWatch watch;
    if (!task.stop && abandonable(steering, task.phase))
      watch = [&comm, frame = task.frame] { return comm.abandoned(frame); };
    const auto report = task.stop
                            ? finalReport(comm.rank(), renderer, task)
                            : renderRects(comm.rank(), renderer, steps.volume(task), steps.tf(task),
                                          job, streamer.get(), task, mine, watch);
    decodeAhead(renderer, steps, task, mine, job);
    // Rank 0 takes the report after rendering its own part, which may take longer than ours.
    comm.gather(master::encode(report), 2 * timeoutMs);
    if (task.stop) break;
    ++summary.framesRendered;
  }
  return summary;
}

}  // namespace

int bandRows(const JobSettings& job) {
  return job.stream ? job.stream->codec.segmentPixels : net::TileCodecSettings{}.segmentPixels;
}

std::vector<voxwall::Rect> bands(const voxwall::Rect& rect, const JobSettings& job) {
  return node::rowBands(rect, bandRows(job));
}

std::vector<std::vector<voxwall::Rect>> firstFrameRects(const JobSettings& job, int ranks) {
  const auto renderers = renderingRanks(job, ranks);
  return byRank(staticSlots(job, int(renderers.size())), renderers, ranks);
}

namespace {

// Rank 0's side of the frame loop: every frame it decides the camera (the path plus what the wall
// sent back), cuts the screen, broadcasts the task, renders its own part, checks and assembles
// every rank's report, re-balances and hands the frame to the writer.
class MasterLoop {
 public:
  MasterLoop(Communicator& comm, node::Backend& backend, const node::RenderVolume& volume,
             const node::TransferFunction& tf, const node::RenderSettings& render,
             const JobSettings& job)
      : comm_(comm),
        volume_(volume),
        tf_(tf),
        job_(job),
        renderers_(renderingRanks(job, comm.size())),
        slots_(int(renderers_.size())),
        staticCut_(staticSlots(job, slots_)),
        done_(prepareOutput(job, &manifest_)),
        jobId_(newJobId()),
        writer_(job.outDir, manifest_),
        streamer_(makeStreamer(job, 0, comm.size())),
        steps_(volume, tf, job),
        renderer_(backend, render),
        steering_(steeringSettings(job)),
        player_(job.time, job.frames, job.stream ? job.time.rate : 0, Clock::now()),
        timeoutMs_(job.watchdogMs) {
    if (job.balance == Balance::Dynamic)
      balancer_.emplace(job.width, job.height, slots_, job.balancer);
    if (job.stream) {
      net::Hello hello;
      hello.rank = 0, hello.rankCount = comm.size();
      hello.wallId = job.stream->wallId, hello.token = job.stream->token;
      hello.jobId = jobId_;
      hello.nextFrame = std::uint64_t(std::find(done_.begin(), done_.end(), false) - done_.begin());
      control_ = std::make_unique<net::ControlChannel>(job.stream->host, job.stream->port, hello);
    }
  }

  bool done(int f) const { return done_[std::size_t(f)]; }

  FrameSummary frame(int f) {
    const auto frameStart = Clock::now();
    renderer_.endAhead();  // its volume may be let go below
    FrameSummary s;
    s.frame = f;
    readWall(f, frameStart, s);
    if (f == firstFrame_) s.probeSeconds = probe(f);
    const FrameChoice choice = steering_.next(s.controls, job_.clock ? job_.clock() : frameStart);
    s.step = choice.step, s.phase = choice.phase;
    s.rects = cut(s.step);
    master::FrameTask t = task(f, s.rects, choice);
    t.timeStep = std::uint32_t(player_.step(f, frameStart));
    s.timeStep = int(t.timeStep);
    expectNext(t);
    if (control_ && job_.time.count() > 1) control_->setPlayback(std::uint64_t(f), player_.state());
    auto taskBytes = master::encode(t);
    comm_.broadcast(taskBytes, timeoutMs_);
    // A command from the wall abandons a refining or full frame: every rank hears it at once.
    AbandonWatch watch;
    bool signalled = false;
    if (steering_.abandonable(choice) && control_)
      watch = [this, &signalled, &t] {
        if (!signalled && control_->pending() > 0) {
          comm_.signalAbandon(t.frame);
          signalled = true;
        }
        return signalled;
      };
    auto own = renderRects(0, renderer_, steps_.volume(t), steps_.tf(t), job_, streamer_.get(), t,
                           t.rects[0], watch);
    decodeAhead(renderer_, steps_, t, t.rects[0], job_);
    const auto gatherStart = Clock::now();
    // Rank 0 keeps its own report as it is; only the others' travel. It goes on watching while
    // the others render.
    auto reportBytes =
        comm_.gather({}, timeoutMs_, watch ? std::function<void()>([&] { watch(); }) : nullptr);
    s.gatherSeconds = since(gatherStart);
    const auto assembleStart = Clock::now();
    voxwall::Image image = assemble(t, std::move(own), reportBytes, s);
    s.assembleSeconds = since(assembleStart);
    if (!job_.outDir.empty()) {
      s.path = framePath(job_, f);
      s.writeWaitSeconds = writer_.push(std::move(image), s.path, job_.background);
    }
    s.frameSeconds = since(frameStart);
    steering_.finished(choice, s.frameSeconds, s.abandoned);
    slowestFrame_ = std::max(slowestFrame_, s.frameSeconds);
    timeoutMs_ = std::max(job_.watchdogMs, int(std::min(4e3 * slowestFrame_, 3.6e6)));
    return s;
  }

  // Every rank's report into the frame's summary (and its picture, when frames are written); the
  // balancer learns from the costs of whole full-resolution frames only: a reduced frame's are of
  // another screen, an abandoned frame's partial.
  voxwall::Image assemble(const master::FrameTask& t, master::RankReport own,
                          const std::vector<std::vector<std::byte>>& reportBytes, FrameSummary& s) {
    voxwall::Image image =
        job_.outDir.empty() ? voxwall::Image() : voxwall::Image(job_.width, job_.height);
    std::vector<node::CostGrid> grids(static_cast<std::size_t>(slots_));
    for (int i = 0; i < slots_; ++i) {
      const int r = renderers_[std::size_t(i)];
      const std::string source = "report of rank " + std::to_string(r);
      auto report = r == 0 ? std::move(own)
                           : master::decodeRankReport(reportBytes[std::size_t(r)], t, source);
      take(report, r, t, source, s, image);
      grids[std::size_t(i)] = std::move(report.costs);
    }
    s.imbalance = imbalance(s.rankSeconds);
    // Abandoned when a rank left its part unfinished (one that finished before the word came
    // sent whole tiles, so the sink hears it from here too); when all had finished, it is whole.
    if (s.abandoned && streamer_) streamer_->abandon(t.frame);
    if (balancer_ && s.step == 1 && !s.abandoned) {
      balancer_->update(grids, s.rankSeconds);
      s.recuts = balancer_->recuts();
    }
    return image;
  }

  // Stop: every rank answers with its memory and leaves the loop.
  void finish(JobSummary& summary) {
    master::FrameTask stop;
    stop.frame = std::uint32_t(job_.frames);
    stop.stop = true;
    stop.screenWidth = job_.width, stop.screenHeight = job_.height;
    stop.cellPixels = job_.balancer.cellPixels;
    stop.rects.resize(std::size_t(comm_.size()));
    stop.watchdogMs = std::uint32_t(timeoutMs_);
    auto stopBytes = master::encode(stop);
    comm_.broadcast(stopBytes, timeoutMs_);
    const auto ownLast = finalReport(0, renderer_, stop);
    const auto finals = comm_.gather({}, timeoutMs_);
    for (int r = 0; r < comm_.size(); ++r) {
      const auto rep = r == 0
                           ? ownLast
                           : master::decodeRankReport(finals[std::size_t(r)], stop,
                                                      "final report of rank " + std::to_string(r));
      summary.memory.push_back(memoryOf(r, rep));
    }
    writer_.finish();
    if (control_) summary.sinkNotes = control_->drainNotes();
    summary.writeSeconds = writer_.totalWriteSeconds();
  }

  // Rank 0 of a streaming job whose frames reached the sink: why the sink presented none of
  // `frames` (waiting up to `wait` for its notes), or empty when it presented one.
  std::string nothingPresented(int frames, std::chrono::milliseconds wait) {
    if (!control_ || control_->waitForPresented(std::uint64_t(frames), wait)) return "";
    const auto notes = control_->drainNotes();
    return notes.empty() ? "the sink said nothing of them" : notes.back();
  }

 private:
  // A steered job with a frame budget predicts what a full frame costs before it renders one,
  // so that its first steered frame keeps the budget: rank 0 renders the first frame's view at
  // 1/16 a side and shares the predicted time among the rendering ranks. 0 where not steered.
  double probe(int f) {
    if (!steering_.interactive() || job_.frameBudgetMs <= 0) return 0;
    node::RankFrame view;
    view.volume = &volume_, view.tf = &tf_;
    view.camera =
        node::orbitCamera(offset_.apply(job_.path.at(f)), node::boundingRadius(volume_.info()));
    view.screenWidth = job_.width, view.screenHeight = job_.height;
    view.cellPixels = job_.balancer.cellPixels;
    const double seconds = renderer_.probe(view).seconds / double(slots_);
    steering_.predictFullFrame(seconds);
    return seconds;
  }

  // What the wall sent since the last frame: its notes and camera commands. A sink that refused
  // the job (token, wall, version, a newer job) shows nothing of it: the job ends.
  void readWall(int f, Clock::time_point now, FrameSummary& s) {
    if (!control_) return;
    control_->setNextFrame(std::uint64_t(f));
    if (const auto why = control_->refused(); !why.empty())
      throw net::SinkRefused("wall sink " + why);
    s.sinkNotes = control_->drainNotes();
    s.controlsPending = [channel = control_.get()] { return channel->pending(); };
    for (const auto& c : control_->drain()) {
      // Play and pause change no picture: they count as no steering; nor do step and seek in a
      // job of one volume (the sink refuses them once it knows; one may arrive before).
      if (player_.take(c, now)) {
        s.controls += job_.time.count() > 1 && (c.command == net::ControlCommand::StepBy ||
                                                c.command == net::ControlCommand::Seek);
      } else {
        ++s.controls;
        offset_.take(c, job_.path.at(f));
      }
    }
  }

  // Each rendering slot's rectangles this frame: at step > 1, the full-screen cut mapped onto the
  // reduced screen (node::reducedRects).
  std::vector<std::vector<voxwall::Rect>> cut(int step) const {
    std::vector<std::vector<voxwall::Rect>> slotRects = staticCut_;
    if (balancer_)
      for (int i = 0; i < slots_; ++i)
        slotRects[std::size_t(i)] = {balancer_->cut()[std::size_t(i)]};
    if (step == 1) return slotRects;
    for (auto& rects : slotRects) rects = node::reducedRects(rects, job_.width, job_.height, step);
    return slotRects;
  }

  // Where the path goes after task t's frame, for decoding ahead (FrameTask::ahead): full frames
  // of a job with a next frame whose camera or time step differ.
  void expectNext(master::FrameTask& t) const {
    const int next = int(t.frame) + 1;
    if (t.step != 1 || next >= job_.frames) return;
    t.aheadCamera =
        node::orbitCamera(offset_.apply(job_.path.at(next)), node::boundingRadius(volume_.info()));
    t.aheadTimeStep = std::uint32_t(player_.expectedStep(next));
    const node::Camera& a = t.camera;
    const node::Camera& b = t.aheadCamera;
    t.ahead = t.aheadTimeStep != t.timeStep || a.eye != b.eye || a.center != b.center ||
              a.up != b.up || a.fovYDeg != b.fovYDeg;
  }

  master::FrameTask task(int f, const std::vector<std::vector<voxwall::Rect>>& slotRects,
                         const FrameChoice& choice) const {
    const int step = choice.step;
    master::FrameTask t;
    t.frame = std::uint32_t(f);
    t.decidedUnixMicros = net::unixMicrosNow();
    t.jobId = jobId_;
    t.camera =
        node::orbitCamera(offset_.apply(job_.path.at(f)), node::boundingRadius(volume_.info()));
    t.step = step;
    t.phase = choice.phase;
    t.screenWidth = net::reducedSide(job_.width, step);
    t.screenHeight = net::reducedSide(job_.height, step);
    t.cellPixels = job_.balancer.cellPixels;
    t.rects = byRank(slotRects, renderers_, comm_.size());
    t.watchdogMs = std::uint32_t(timeoutMs_);
    return t;
  }

  // Checks rank r's report against the task (every assigned rectangle must come back, or the
  // frame would be shown incomplete), pastes its pixels and adds it to the frame's summary.
  void take(const master::RankReport& report, int r, const master::FrameTask& t,
            const std::string& source, FrameSummary& s, voxwall::Image& image) const {
    const auto& asked = t.rects[std::size_t(r)];
    if (report.rank != r)
      throw FormatError(source, "claims to be rank " + std::to_string(report.rank));
    if (report.tiles.size() != asked.size())
      throw FormatError(source, "has " + std::to_string(report.tiles.size()) + " tiles, " +
                                    std::to_string(asked.size()) + " were asked for");
    if (report.pixels != !job_.outDir.empty())
      throw FormatError(source, report.pixels ? "sent pixels nobody asked for"
                                              : "sent no pixels, the frame is to be written");
    for (std::size_t i = 0; i < report.tiles.size(); ++i) {
      if (!(report.tiles[i].rect == asked[i]))
        throw FormatError(source, "sent a tile that was not asked for");
      if (report.pixels) image.paste(report.tiles[i].image, report.tiles[i].rect);
    }
    if (report.streamRefused)
      throw net::SinkRefused("rank " + std::to_string(r) + ": " + report.streamError);
    s.streamedRanks += report.streamed;
    s.abandoned = s.abandoned || report.abandoned;
    if (!report.streamed && s.streamError.empty() && job_.stream && !report.tiles.empty())
      s.streamError = "rank " + std::to_string(r) + ": " + report.streamError;
    s.encodeSeconds = std::max(s.encodeSeconds, report.encodeSeconds);
    s.streamedBytes += report.streamedBytes;
    s.ranks.push_back(r);
    s.rankSeconds.push_back(report.renderSeconds);
    s.rankPages.push_back(report.pages);
    s.rankMemory.push_back(memoryOf(r, report));
    s.samples += report.samples;
    s.rays += report.rays;
    s.latticeStride = std::max(s.latticeStride, report.latticeStride);
    s.renderSeconds = std::max(s.renderSeconds, report.renderSeconds);
  }

  Communicator& comm_;
  const node::RenderVolume& volume_;
  const node::TransferFunction& tf_;
  const JobSettings& job_;
  const std::vector<int> renderers_;
  const int slots_;
  const std::vector<std::vector<voxwall::Rect>> staticCut_;
  nlohmann::json manifest_;
  const std::vector<bool> done_;
  const std::uint64_t jobId_;
  FrameWriter writer_;
  const std::unique_ptr<net::TileStreamer> streamer_;
  std::optional<LoadBalancer> balancer_;
  StepVolumes steps_;  // each frame's time step (before renderer_: its pass ahead reads steps_)
  node::RankRenderer renderer_;
  std::unique_ptr<net::ControlChannel> control_;
  CameraOffset offset_;
  Steering steering_;  // each frame's step, and which frames a command abandons
  TimePlayer player_;
  double slowestFrame_ = 0;
  int timeoutMs_;
  // The first frame this run renders (--resume skips those done).
  const int firstFrame_ = int(std::find(done_.begin(), done_.end(), false) - done_.begin());
};

}  // namespace

JobSummary runRenderJob(Communicator& comm, node::Backend& backend,
                        const node::RenderVolume& volume, const node::TransferFunction& tf,
                        const node::RenderSettings& render, const JobSettings& job,
                        const std::function<void(const FrameSummary&)>& onFrame) {
  if (job.frames < 1) throw std::invalid_argument("--frames must be at least 1");
  if (comm.rank() != 0) return runWorker(comm, backend, volume, tf, render, job);
  const auto jobStart = Clock::now();
  MasterLoop loop(comm, backend, volume, tf, render, job);
  JobSummary summary;
  // Since when no frame's tiles reached the wall sink, whether one ever did, and the last reason.
  Clock::time_point unreachedSince{};  // meaningful while `unreached`
  bool unreached = false, reached = false;
  std::string missed;
  const std::string sinkName =
      job.stream ? "wall sink " + job.stream->host + ":" + std::to_string(job.stream->port) : "";
  for (int f = 0; f < job.frames; ++f) {
    if (loop.done(f)) {
      ++summary.framesSkipped;
      continue;
    }
    const FrameSummary s = loop.frame(f);
    ++summary.framesRendered;
    if (onFrame) onFrame(s);
    if (!job.stream) continue;
    if (s.streamError.empty()) {
      unreached = false;
      reached = true;
      continue;
    }
    missed = s.streamError;
    if (!unreached) {
      unreached = true;
      unreachedSince = Clock::now();
    }
    if (since(unreachedSince) > job.stream->deadlineSeconds)
      throw net::NetError(sinkName + ": no tiles reached it for " +
                          formatLine("%g", job.stream->deadlineSeconds) + " s (" + missed +
                          "); the job stops rather than render for nobody");
  }
  loop.finish(summary);
  if (job.stream && summary.framesRendered > 0 && !reached)
    throw net::NetError(sinkName + ": none of the " + std::to_string(summary.framesRendered) +
                        " frame(s) reached it (" + missed + ")");
  // Tiles that reached the sink may still not show (a frame dropped incomplete, refused): a
  // job none of whose frames the sink presented fails too.
  if (job.stream && summary.framesRendered > 0) {
    const auto wait =
        std::chrono::milliseconds(std::int64_t(1000 * std::min(10.0, job.stream->deadlineSeconds)));
    if (const std::string why = loop.nothingPresented(summary.framesRendered, wait); !why.empty())
      throw net::NetError(sinkName + ": it presented none of the " +
                          std::to_string(summary.framesRendered) + " frame(s) (" + why + ")");
  }
  summary.seconds = since(jobStart);
  return summary;
}

}  // namespace voxwall::master
