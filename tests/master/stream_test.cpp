// The render job streaming to a sink on loopback: N fake ranks (threads) render, compress and
// send their tiles; the sink assembles and writes per-display images.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <functional>
#include <thread>
#include <voxwall/codec/generators.hpp>
#include <voxwall/master/render_job.hpp>
#include <voxwall/walls/sink.hpp>

#include "support/fake_communicator.hpp"
#include "support/sink_runner.hpp"
#include "support/temp_dir.hpp"
#include "support/wait_until.hpp"

using namespace voxwall;
namespace fs = std::filesystem;

namespace {

const node::RenderVolume& volume() {
  static const auto v = node::RenderVolume::fromVolume(codec::generateSheppLogan(40), 8);
  return v;
}
node::TransferFunction tf() { return node::TransferFunction::preset("mri").rescaled(0, 255); }

walls::Wall wall() {
  return walls::parseWall(R"({"wall": "mini", "display": {"width": 48, "height": 36},
      "bezel_px": {"x": 3, "y": 5}, "grid": {"columns": 2, "rows": 2}})",
                          "mini");
}

// A sink for the test wall writing to `out`, on `port` (0: any free one).
std::unique_ptr<test::SinkRunner> startSink(const std::string& out, std::uint16_t port = 0) {
  walls::SinkSettings s;
  s.wall = wall();
  s.outDir = out;
  s.listenPort = port;
  return std::make_unique<test::SinkRunner>(s);
}

master::JobSettings streamJob(std::uint16_t port, net::TileCodec codec, int frames) {
  master::JobSettings job;
  const auto w = wall();
  job.width = w.width, job.height = w.height;
  job.frames = frames;
  job.path = master::CameraPath::orbit({}, 30);
  job.watchdogMs = 20000;
  job.balancer.cellPixels = 8;
  master::StreamSettings st;
  st.host = "127.0.0.1", st.port = port, st.wallId = w.id;
  st.codec.codec = codec;
  st.codec.segmentPixels = 16;  // several segments per rank
  st.codec.threads = 1;
  job.stream = st;
  return job;
}

void runStreamingJob(int ranks, const master::JobSettings& job,
                     const std::function<void(const master::FrameSummary&)>& onFrame = {},
                     const std::function<std::unique_ptr<node::Backend>()>& makeBackend = {}) {
  const auto errors = test::runRanks(ranks, [&](master::Communicator& comm) {
    auto backend = makeBackend ? makeBackend() : node::makeCpuBackend(1);
    master::runRenderJob(comm, *backend, volume(), tf(), {}, job, onFrame);
  });
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
}

// The single-rank reference frame over black, as the sink shows it: at `step` > 1 rendered on
// the reduced screen and upsampled (every pixel repeats the reduced pixel of its block).
voxwall::Image reference(const master::JobSettings& job, int frame,
                         const master::CameraOffset& offset = {}, int step = 1) {
  const auto camera =
      node::orbitCamera(offset.apply(job.path.at(frame)), node::boundingRadius(volume().info()));
  const int w = net::reducedSide(job.width, step), h = net::reducedSide(job.height, step);
  const auto plan = node::planFrame(volume(), camera, w, h, tf(), {});
  voxwall::Image reduced;
  node::makeCpuBackend(1)->render(volume(), plan, {0, 0, w, h}, reduced);
  voxwall::Image image(job.width, job.height);
  for (int y = 0; y < job.height; ++y)
    for (int x = 0; x < job.width; ++x) image.at(x, y) = reduced.at(x / step, y / step);
  for (auto& p : image.pixels) p |= 0xff000000u;
  return image;
}

std::string displayFile(const std::string& dir, int frame, const std::string& display) {
  char name[64];
  std::snprintf(name, sizeof name, "frame_%05d_%s.png", frame, display.c_str());
  return (fs::path(dir) / name).string();
}

// Waits until the sink has settled `frames` frames (presented or dropped) and its file writer has
// written (or skipped, when it fell behind) every presented one: tests check every frame written.
bool waitSettled(test::SinkRunner& sink, int frames) {
  return sink.waitFor([frames](const walls::SinkStats& s) {
    return s.framesPresented + s.framesDropped + s.framesSuperseded >= frames &&
           s.framesWritten + s.framesNotWritten == s.framesPresented;
  });
}

// Rank 0, after a frame, sends the wall a command and waits until it has arrived on rank 0: the
// next frame takes it.
void steerOnce(test::SinkRunner& sink, const master::FrameSummary& f) {
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }))
      << "rank 0's control connection did not come up";
  sink.sink().sendControl(net::Control{net::ControlCommand::Rotate, 40, 0});
  ASSERT_TRUE(f.controlsPending);
  ASSERT_TRUE(test::waitUntil([&] { return f.controlsPending() >= 1; }))
      << "the command did not reach rank 0";
}

// A job's clock (JobSettings::clock) that moves only when the test advances it: the decisions
// that wait on time (steering settling, a streamer's reconnect back-off) follow the frames, never
// the machine's speed.
class TestClock {
 public:
  void advance(std::chrono::milliseconds by) { added_ += by.count(); }
  std::function<std::chrono::steady_clock::time_point()> clock() {
    return [this] { return start_ + std::chrono::milliseconds(added_.load()); };
  }

 private:
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::atomic<std::int64_t> added_{0};
};

// Checks every frame the sink wrote against the single-rank render; returns how many it wrote.
int checkShownFrames(const std::string& dir, const master::JobSettings& job, double minPsnrDb) {
  int shown = 0;
  for (int f = 0; f < job.frames; ++f) {
    int present = 0;
    for (const auto& d : wall().displays) present += fs::exists(displayFile(dir, f, d.name));
    if (present == 0) continue;
    EXPECT_EQ(present, 4) << "frame " << f << " was written partly";
    const auto ref = reference(job, f);
    for (const auto& d : wall().displays) {
      const auto image = voxwall::readImage(displayFile(dir, f, d.name));
      if (minPsnrDb == 0)
        EXPECT_EQ(image.pixels, ref.crop(d.rect).pixels) << "frame " << f << " " << d.name;
      else
        EXPECT_GE(voxwall::compareImages(image, ref.crop(d.rect)).psnrDb, minPsnrDb)
            << "frame " << f << " " << d.name;
    }
    ++shown;
  }
  return shown;
}

}  // namespace

// Lossless tiles from 4 ranks: every display image equals the crop of the single-rank render.
TEST(Stream, FourRanksLosslessEqualCropsOfTheSingleRankRender) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  const auto job = streamJob(sink->port(), net::TileCodec::Deflate, 3);
  runStreamingJob(4, job);
  ASSERT_TRUE(waitSettled(*sink, 3));
  sink->stop();
  const auto stats = sink->sink().stats();
  EXPECT_EQ(stats.framesDropped, 0);
  EXPECT_EQ(checkShownFrames(dir.path("wall"), job, 0), stats.framesPresented);
  // The newest frame is always shown.
  EXPECT_TRUE(fs::exists(displayFile(dir.path("wall"), 2, "r1c1")));
}

// The CPU backend, noting the tallest rectangle it was asked to render.
class TallestTile : public node::Backend {
 public:
  std::string name() const override { return "cpu (tallest tile noted)"; }
  int tallest() const { return tallest_.load(); }

 protected:
  node::TileStats renderTile(const node::RenderVolume& v, const node::FramePlan& plan,
                             const voxwall::Rect& tile, voxwall::Image& out, node::CostGrid* costs,
                             const std::atomic<bool>* stop) override {
    for (int t = tallest_.load();
         tile.height > t && !tallest_.compare_exchange_weak(t, tile.height);)
      ;
    return cpu_->render(v, plan, tile, out, costs, stop);
  }

 private:
  std::unique_ptr<node::Backend> cpu_ = node::makeCpuBackend(1);
  std::atomic<int> tallest_{0};
};

// A rank streaming to the sink keeps one band of its pixels at a time: it renders, encodes and
// sends its rectangles in rows of the codec's segment size, and the wall shows the same frames.
TEST(Stream, RanksRenderAndSendInBandsOfSegmentRows) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  const auto job = streamJob(sink->port(), net::TileCodec::Deflate, 2);
  TallestTile backend;
  const auto errors = test::runRanks(2, [&](master::Communicator& comm) {
    master::runRenderJob(comm, backend, volume(), tf(), {}, job);
  });
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  ASSERT_TRUE(waitSettled(*sink, 2));
  sink->stop();
  // Two ranks cut a 77-row screen: each has more rows than a 16-row segment.
  EXPECT_EQ(backend.tallest(), job.stream->codec.segmentPixels);
  EXPECT_EQ(checkShownFrames(dir.path("wall"), job, 0), sink->sink().stats().framesPresented);
  EXPECT_GE(sink->sink().stats().framesPresented, 1);
}

TEST(Stream, JpegTilesKeep40Decibels) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  const auto job = streamJob(sink->port(), net::TileCodec::Jpeg, 2);
  runStreamingJob(3, job);
  ASSERT_TRUE(waitSettled(*sink, 2));
  sink->stop();
  EXPECT_GE(checkShownFrames(dir.path("wall"), job, 40.0), 1);
}

// A command typed at the sink changes the camera of later frames.
TEST(Stream, ControlFromTheWallMovesTheCamera) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  auto job = streamJob(sink->port(), net::TileCodec::Deflate, 4);
  job.path = master::CameraPath::orbit({}, 0);  // a still camera
  job.interactiveStep = 1;  // full frames while steered, to compare them exactly (mpi.interactive)
  runStreamingJob(2, job, [&](const master::FrameSummary& f) {
    if (f.frame == 0) steerOnce(*sink, f);
  });
  ASSERT_TRUE(waitSettled(*sink, 4));
  sink->stop();
  master::CameraOffset turned;
  turned.azimuthDeg = 40;
  const auto before = reference(job, 0), after = reference(job, 3, turned);
  const auto screen = wall();
  const auto& d = screen.displays[0];
  EXPECT_EQ(voxwall::readImage(displayFile(dir.path("wall"), 0, d.name)).pixels,
            before.crop(d.rect).pixels);
  EXPECT_EQ(voxwall::readImage(displayFile(dir.path("wall"), 3, d.name)).pixels,
            after.crop(d.rect).pixels);
  EXPECT_NE(before.pixels, after.pixels);
}

// The sink dies and comes back mid-run: the job goes on, frames in flight are lost, every frame
// the new sink writes is whole and right.
TEST(Stream, SinkRestartLosesOnlyFramesInFlight) {
  test::TempDir dir;
  auto first = startSink(dir.path("a"));
  const std::uint16_t port = first->port();
  std::unique_ptr<test::SinkRunner> second;
  const int frames = 30;
  auto job = streamJob(port, net::TileCodec::Deflate, frames);
  TestClock clock;
  job.clock = clock.clock();
  std::string downtimeError;
  runStreamingJob(3, job, [&](const master::FrameSummary& f) {
    if (f.frame > 5 && f.frame < 10 && downtimeError.empty()) downtimeError = f.streamError;
    if (f.frame == 5) first->stop();  // the sink process dies
    if (f.frame == 10) second = startSink(dir.path("b"), port);
    // Past the longest back-off (5 s): every rank tries the new sink at its next frame.
    if (f.frame >= 10) clock.advance(std::chrono::seconds(6));
  });
  ASSERT_TRUE(second);
  // While no sink listened, rank 0 heard which rank missed it and why.
  EXPECT_EQ(downtimeError.rfind("rank ", 0), 0u) << "'" << downtimeError << "'";
  second->stop();
  EXPECT_GE(first->sink().stats().framesPresented, 1);
  EXPECT_GE(second->sink().stats().framesPresented, 2) << "the ranks did not reconnect";
  // Every frame either sink wrote is whole and right.
  const int checked =
      checkShownFrames(dir.path("a"), job, 0) + checkShownFrames(dir.path("b"), job, 0);
  EXPECT_GE(checked, 6);
  EXPECT_LT(checked, frames);  // frames in flight while no sink listened are gone
}

// While commands arrive the frames are interactive (1/4 per side, upsampled by the sink); once
// the camera settled, the full frame equals the single-process render of the turned camera.
TEST(Stream, SteeredFramesAreInteractiveUntilTheCameraSettles) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  auto job = streamJob(sink->port(), net::TileCodec::Deflate, 8);
  job.path = master::CameraPath::orbit({}, 0);
  job.interactiveStep = 4;
  job.settleSeconds = 0.3;
  TestClock clock;
  job.clock = clock.clock();
  std::vector<int> steps;
  runStreamingJob(2, job, [&](const master::FrameSummary& f) {
    steps.push_back(f.step);
    if (f.frame == 0) {
      steerOnce(*sink, f);
    } else {
      // 150 ms of the job's clock a frame: 0.3 s after the command the camera has settled,
      // well before the last frame.
      clock.advance(std::chrono::milliseconds(150));
    }
  });
  ASSERT_TRUE(waitSettled(*sink, 8));
  sink->stop();
  ASSERT_EQ(steps.size(), 8u);
  EXPECT_EQ(steps[0], 1);
  EXPECT_EQ(steps[1], 4);  // the frame that took the command
  EXPECT_EQ(steps[7], 1);  // over a second later: settled
  master::CameraOffset turned;
  turned.azimuthDeg = 40;
  const auto after = reference(job, 7, turned);
  for (const auto& d : wall().displays) {
    EXPECT_EQ(voxwall::readImage(displayFile(dir.path("wall"), 7, d.name)).pixels,
              after.crop(d.rect).pixels)
        << d.name;
    // The interactive frame is whole: every display's picture was written.
    EXPECT_TRUE(fs::exists(displayFile(dir.path("wall"), 1, d.name))) << d.name;
  }
}

namespace {

// The CPU backend, except that while `stall` is set a full-resolution tile does not finish
// until the render is told to stop (a full frame far slower than the test): counts the tiles
// that were stopped.
class StallingBackend final : public node::Backend {
 public:
  StallingBackend(std::atomic<bool>& stall, std::atomic<int>& stalling, std::atomic<int>& stopped)
      : stall_(stall), stalling_(stalling), stopped_(stopped) {}
  std::string name() const override { return "stalling"; }

 protected:
  node::TileStats renderTile(const node::RenderVolume& v, const node::FramePlan& plan,
                             const voxwall::Rect& tile, voxwall::Image& out, node::CostGrid* costs,
                             const std::atomic<bool>* stop) override {
    if (stall_ && stop && plan.ray.screen.x == wall().width) {
      ++stalling_;
      // Until the frame is abandoned; the deadline only keeps a broken test from hanging.
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
      while (!stop->load() && std::chrono::steady_clock::now() < deadline)
        std::this_thread::yield();
      --stalling_;
    }
    const auto stats = cpu_->render(v, plan, tile, out, costs, stop);
    if (stats.stopped) ++stopped_;
    return stats;
  }

 private:
  std::unique_ptr<node::Backend> cpu_ = node::makeCpuBackend(1);
  std::atomic<bool>& stall_;
  std::atomic<int>& stalling_;
  std::atomic<int>& stopped_;
};

// Sends `control` once every rank renders a stalled tile (or after 20 s: then the test fails on
// what follows).
void sendWhenStalled(test::SinkRunner& sink, std::atomic<int>& stalling, int ranks,
                     const net::Control& control) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (stalling < ranks && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
  sink.sink().sendControl(control);
}

// Runs `job` on 2 ranks whose frame 1 does not finish until a command, sent once both render it,
// abandons it (`rotate 40 0`); returns every frame's summary and, in `stopped`, how many tiles
// were left unfinished.
std::vector<master::FrameSummary> runWithFrameOneAbandoned(const master::JobSettings& job,
                                                           test::SinkRunner& sink,
                                                           int* stopped = nullptr) {
  std::atomic<bool> stall{false};
  std::atomic<int> stalling{0}, unfinished{0};
  std::vector<master::FrameSummary> frames;
  std::thread commander;
  runStreamingJob(
      2, job,
      [&](const master::FrameSummary& f) {
        frames.push_back(f);
        if (f.frame == 0) {
          stall = true;
          commander = std::thread([&] {
            sendWhenStalled(sink, stalling, 2, {net::ControlCommand::Rotate, 40, 0});
          });
        }
        if (f.frame == 1) stall = false;
      },
      [&] { return std::make_unique<StallingBackend>(stall, stalling, unfinished); });
  commander.join();
  if (stopped) *stopped = unfinished;
  return frames;
}

}  // namespace

// A command that arrives while a full frame renders abandons it on every rank: the sink drops it
// as superseded, and the next frame is a steered one with the new camera, equal to a batch render
// of that camera at that step.
TEST(Stream, ACommandDuringAFullFrameAbandonsItAndTheNextFrameHasTheNewCamera) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  auto job = streamJob(sink->port(), net::TileCodec::Deflate, 4);
  job.path = master::CameraPath::orbit({}, 0);
  job.settleSeconds = 3600;  // stay steered: frames 2 and 3 are interactive
  int stopped = 0;
  const auto frames = runWithFrameOneAbandoned(job, *sink, &stopped);
  ASSERT_TRUE(waitSettled(*sink, 4)) << sink->log();
  sink->stop();
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_FALSE(frames[0].abandoned);
  EXPECT_TRUE(frames[1].abandoned);
  EXPECT_EQ(frames[1].step, 1);
  EXPECT_GE(stopped, 2);  // both ranks left their tiles unfinished
  EXPECT_EQ(frames[2].step, 4);
  EXPECT_EQ(frames[2].phase, net::FramePhase::Interactive);
  EXPECT_FALSE(frames[2].abandoned);
  const auto stats = sink->sink().stats();
  EXPECT_EQ(stats.framesSuperseded, 1);
  EXPECT_NE(sink->log().find("frame 1 superseded: the render job abandoned it"), std::string::npos)
      << sink->log();
  EXPECT_FALSE(fs::exists(displayFile(dir.path("wall"), 1, "r0c0")));
  master::CameraOffset turned;
  turned.azimuthDeg = 40;
  const auto after = reference(job, 2, turned, 4);
  for (const auto& d : wall().displays)
    EXPECT_EQ(voxwall::readImage(displayFile(dir.path("wall"), 2, d.name)).pixels,
              after.crop(d.rect).pixels)
        << d.name;
}

// Once the camera settled the picture refines: steps 4, 2 and 1 in order, each shown; the full
// frame equals a batch render of the moved camera exactly. A batch job (it writes frames) takes
// the same command without reducing, refining or abandoning anything.
TEST(Stream, RefinementShowsStepsInOrderAndEndsAtTheBatchFrame) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  auto job = streamJob(sink->port(), net::TileCodec::Deflate, 5);
  job.path = master::CameraPath::orbit({}, 0);
  job.settleSeconds = 0;  // settled as soon as the command was taken: refine at once
  // Frame 1 stalls until the command abandons it, so frame 2 is the first to take it.
  const auto frames = runWithFrameOneAbandoned(job, *sink);
  ASSERT_TRUE(waitSettled(*sink, 5)) << sink->log();
  sink->stop();
  ASSERT_EQ(frames.size(), 5u);
  ASSERT_TRUE(frames[1].abandoned);
  EXPECT_EQ(frames[2].step, 4);
  EXPECT_EQ(frames[2].phase, net::FramePhase::Refining);
  EXPECT_EQ(frames[3].step, 2);
  EXPECT_EQ(frames[3].phase, net::FramePhase::Refining);
  EXPECT_EQ(frames[4].step, 1);
  EXPECT_EQ(frames[4].phase, net::FramePhase::Full);
  EXPECT_NE(sink->log().find("frame 2 presented"), std::string::npos) << sink->log();
  EXPECT_NE(sink->log().find("refining 1/4"), std::string::npos) << sink->log();
  EXPECT_NE(sink->log().find("refining 1/2"), std::string::npos) << sink->log();
  master::CameraOffset turned;
  turned.azimuthDeg = 40;
  const auto full = reference(job, 4, turned);
  for (const auto& d : wall().displays)
    EXPECT_EQ(voxwall::readImage(displayFile(dir.path("wall"), 4, d.name)).pixels,
              full.crop(d.rect).pixels)
        << d.name;
}

TEST(Stream, BatchJobsNeverAbandonOrRefine) {
  test::TempDir dir;
  auto sink = startSink(dir.path("wall"));
  auto job = streamJob(sink->port(), net::TileCodec::Deflate, 3);
  job.outDir = dir.path("frames");  // a batch job: it writes its frames
  job.path = master::CameraPath::orbit({}, 0);
  std::atomic<bool> stall{false};
  std::atomic<int> stalling{0}, stopped{0};
  std::vector<master::FrameSummary> frames;
  runStreamingJob(
      2, job,
      [&](const master::FrameSummary& f) {
        frames.push_back(f);
        if (f.frame == 0) sink->sink().sendControl({net::ControlCommand::Rotate, 40, 0});
      },
      [&] { return std::make_unique<StallingBackend>(stall, stalling, stopped); });
  ASSERT_EQ(frames.size(), 3u);
  for (const auto& f : frames) {
    EXPECT_FALSE(f.abandoned) << f.frame;
    EXPECT_EQ(f.step, 1) << f.frame;
    EXPECT_EQ(f.phase, net::FramePhase::Full) << f.frame;
  }
  EXPECT_EQ(stopped.load(), 0);
  ASSERT_TRUE(waitSettled(*sink, 3)) << sink->log();
  EXPECT_EQ(sink->sink().stats().framesSuperseded, 0);
}

// A wall file with the sink's wall id but other displays (or another screen): the job showed no
// frame and exited 0. Rank 0's streamer compares the sink's Welcome with its own wall: the job
// fails at once, in one line that says what differs.
TEST(Stream, AWallOtherThanTheSinksFailsTheJob) {
  test::TempDir dir;
  auto sink = startSink(dir.path("out"));
  auto job = streamJob(sink->port(), net::TileCodec::Raw, 3);
  for (const auto& d : wall().displays) job.stream->displays.push_back(d.rect);
  job.stream->displays[1].width -= 2;
  try {
    runStreamingJob(1, job);
    ADD_FAILURE() << "a job for other displays ran";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("the sink's wall mini has a display at"),
              std::string::npos)
        << e.what();
  }
  job.stream->displays.clear();
  job.width += 4;
  try {
    runStreamingJob(1, job);
    ADD_FAILURE() << "a job for another screen ran";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("screen where this job renders"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(sink->sink().stats().framesPresented, 0);
}
