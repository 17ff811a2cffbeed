#include <gtest/gtest.h>

#include <filesystem>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/master/render_job.hpp>

#include "support/fake_communicator.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
namespace fs = std::filesystem;

namespace {

const node::RenderVolume& testVolume() {
  // 8-voxel bricks, so tile edges at odd pixels cut through bricks.
  static const auto volume = node::RenderVolume::fromVolume(codec::generateSheppLogan(40), 8);
  return volume;
}

node::TransferFunction testTf() { return node::TransferFunction::preset("mri").rescaled(0, 255); }

master::JobSettings testJob(const std::string& dir, int frames = 3) {
  master::JobSettings job;
  job.width = 61, job.height = 47;  // odd sizes: strips and bisections cut bricks
  job.frames = frames;
  job.path = master::CameraPath::orbit({}, 25);
  job.outDir = dir;
  job.watchdogMs = 20000;
  job.balancer.cellPixels = 8;
  return job;
}

// Runs the job on `ranks` fake ranks; rethrows rank 0's error; returns rank 0's summary.
master::JobSummary runJob(int ranks, const master::JobSettings& job,
                          std::vector<master::FrameSummary>* frames = nullptr) {
  master::JobSummary summary;
  const auto errors = test::runRanks(ranks, [&](master::Communicator& comm) {
    auto backend = node::makeCpuBackend(1);
    auto result = master::runRenderJob(comm, *backend, testVolume(), testTf(), {}, job,
                                       [&](const master::FrameSummary& f) {
                                         if (frames) frames->push_back(f);
                                       });
    if (comm.rank() == 0) summary = result;
  });
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  return summary;
}

void expectSameFrames(const std::string& a, const std::string& b, int frames) {
  for (int f = 0; f < frames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.png", f);
    const auto ia = voxwall::readImage((fs::path(a) / name).string());
    const auto ib = voxwall::readImage((fs::path(b) / name).string());
    ASSERT_EQ(ia.width, ib.width);
    EXPECT_EQ(ia.pixels, ib.pixels) << name << " differs between " << a << " and " << b;
  }
}

}  // namespace

TEST(RenderJob, SingleRankWritesOneFilePerFrameAndOrbits) {
  test::TempDir dir;
  std::vector<master::FrameSummary> frames;
  const auto summary = runJob(1, testJob(dir.path("one")), &frames);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(summary.framesRendered, 3);
  for (int f = 0; f < 3; ++f) {
    EXPECT_TRUE(fs::exists(frames[std::size_t(f)].path));
    EXPECT_GT(frames[std::size_t(f)].samples, 0u);
  }
  EXPECT_NE(voxwall::readImage(frames[0].path).pixels, voxwall::readImage(frames[1].path).pixels);
  // Only the frames and the job manifest are left (no temporaries).
  int files = 0;
  for (auto& e : fs::directory_iterator(dir.path("one"))) files += e.is_regular_file();
  EXPECT_EQ(files, 4);
  EXPECT_TRUE(fs::exists(dir.path("one/voxwall-job.json")));
}

// The image from N ranks equals the single-rank image pixel for pixel, for every cut.
// Once the view settles (a frame that decodes no page after frames that did), none of the
// mapped file stays resident: the voxels live in the pages, and the compressed bytes come back
// from the system's page cache only when a page is decoded anew. A frame that decoded keeps them
// (the next may decode more), and so does a job over its budget; a raw volume's rays read the
// file itself, which it keeps.
TEST(RenderJob, AFrameThatDecodedPagesLeavesNoneOfTheMappedFileResident) {
  if (node::cpuPacketLanes() == 1) GTEST_SKIP() << "no SIMD packets on this CPU: no pages";
  test::TempDir dir;
  master::JobSettings job = testJob("", 2);
  job.width = 96, job.height = 80;
  job.path = master::CameraPath::orbit({}, 0);  // still: frame 2 decodes nothing
  auto run = [&](const node::RenderVolume& volume,
                 std::uint64_t budget = node::kDefaultDecodeCacheBytes) {
    auto backend = node::makeCpuBackend(1, true, budget);
    const auto errors = test::runRanks(1, [&](master::Communicator& comm) {
      master::runRenderJob(comm, *backend, volume, testTf(), {}, job, {});
    });
    if (errors[0]) std::rethrow_exception(errors[0]);
    return node::cpuDecodeCacheUse(*backend);
  };
  const auto ksvd = node::RenderVolume::open(std::string(VOXWALL_TEST_DATA_DIR) +
                                             "/reference/phantom64_ksvd.vwz");
  const auto opened = ksvd.mappedResidentBytes();
  if (!opened) GTEST_SKIP() << "/proc/self/smaps cannot tell what is resident here";
  ASSERT_GT(*opened, 0u) << "opening reads every byte (checksums)";
  job.frames = 1;
  ASSERT_GT(run(ksvd).misses, 0u);
  EXPECT_GT(ksvd.mappedResidentBytes().value_or(0), 0u) << "released before the view settled";
  job.frames = 2;
  const auto pages = run(ksvd);
  ASSERT_GT(pages.misses, 0u) << "the frames decoded no pages";
  EXPECT_EQ(pages.evictions, 0u);
  EXPECT_EQ(ksvd.mappedResidentBytes(), std::optional<std::uint64_t>(0));

  // Over the budget (a page), every frame decodes again: the file stays.
  const auto tight = node::RenderVolume::open(std::string(VOXWALL_TEST_DATA_DIR) +
                                              "/reference/phantom64_ksvd.vwz");
  ASSERT_GT(tight.mappedResidentBytes().value_or(0), 0u);
  const auto squeezed = run(tight, pages.pageBytes);
  ASSERT_GT(squeezed.evictions, 0u) << "one page held every page";
  EXPECT_GT(tight.mappedResidentBytes().value_or(0), 0u);

  voxwall::Progress quiet;
  codec::writeContainer(codec::rawbricks::encode(codec::generateSheppLogan(64), {}, quiet),
                        dir.path("raw.vwz"));
  const auto raw = node::RenderVolume::open(dir.path("raw.vwz"));
  raw.releaseMappedPages();
  EXPECT_EQ(run(raw).misses, 0u);
  EXPECT_GT(raw.mappedResidentBytes().value_or(0), 0u) << "the rays' bricks stay resident";
}

TEST(RenderJob, ManyRanksEqualOneRankPixelForPixel) {
  test::TempDir dir;
  runJob(1, testJob(dir.path("ref"), 4));
  for (int ranks : {2, 3, 4}) {
    for (int mode = 0; mode < 4; ++mode) {
      auto job = testJob(dir.path("r" + std::to_string(ranks) + "m" + std::to_string(mode)), 4);
      job.balance = mode == 0 ? master::Balance::Dynamic : master::Balance::Static;
      if (mode == 2) job.staticTilesX = 3, job.staticTilesY = 5;  // several tiles per rank
      if (mode == 3) job.masterRenders = false;
      std::vector<master::FrameSummary> frames;
      runJob(ranks, job, &frames);
      ASSERT_EQ(frames.size(), 4u);
      EXPECT_EQ(frames[0].ranks.size(), std::size_t(mode == 3 ? ranks - 1 : ranks));
      expectSameFrames(dir.path("ref"), job.outDir, 4);
    }
  }
}

TEST(RenderJob, ResumeRendersOnlyTheMissingFrames) {
  test::TempDir dir;
  const auto out = dir.path("frames");
  runJob(2, testJob(dir.path("ref"), 5));
  auto job = testJob(out, 5);
  runJob(3, job);
  // As a killed run leaves it: two frames missing, one temporary half-written.
  fs::remove(out + "/frame_00001.png");
  fs::remove(out + "/frame_00004.png");
  test::writeFile(out + "/frame_00004.png.tmp.123.png", "half a frame");
  const auto before = fs::last_write_time(out + "/frame_00002.png");
  job.resume = true;
  const auto summary = runJob(3, job);
  EXPECT_EQ(summary.framesSkipped, 3);
  EXPECT_EQ(summary.framesRendered, 2);
  EXPECT_EQ(fs::last_write_time(out + "/frame_00002.png"), before);
  EXPECT_FALSE(fs::exists(out + "/frame_00004.png.tmp.123.png"));
  expectSameFrames(dir.path("ref"), out, 5);
}

TEST(RenderJob, ResumeRefusesFramesOfOtherSettings) {
  test::TempDir dir;
  auto job = testJob(dir.path("frames"), 2);
  job.manifest = R"({"step": 0.25})";
  runJob(1, job);
  job.resume = true;
  job.manifest = R"({"step": 0.5})";
  try {
    runJob(1, job);
    FAIL() << "resumed frames made with another step";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("step"), std::string::npos) << e.what();
  }
  // Frames without a manifest: nobody knows how they were made.
  fs::remove(dir.path("frames/voxwall-job.json"));
  EXPECT_THROW(runJob(1, job), FormatError);
}

namespace {

// A rank that stops answering (test stand-in for a hung process).
class SlowBackend final : public node::Backend {
 public:
  explicit SlowBackend(int ms) : inner_(node::makeCpuBackend(1)), ms_(ms) {}
  std::string name() const override { return "slow"; }

 protected:
  node::TileStats renderTile(const node::RenderVolume& v, const node::FramePlan& p,
                             const voxwall::Rect& t, voxwall::Image& out, node::CostGrid* c,
                             const std::atomic<bool>* stop) override {
    std::this_thread::sleep_for(std::chrono::milliseconds(ms_));
    return inner_->render(v, p, t, out, c, stop);
  }

 private:
  std::unique_ptr<node::Backend> inner_;
  int ms_;
};

}  // namespace

TEST(RenderJob, WatchdogNamesTheRankThatStoppedAnswering) {
  test::TempDir dir;
  auto job = testJob("", 2);
  job.watchdogMs = 1000;  // generous: a loaded CI machine must not make rank 1 look stalled
  const auto errors = test::runRanks(3, [&](master::Communicator& comm) {
    std::unique_ptr<node::Backend> backend =
        comm.rank() == 2 ? std::unique_ptr<node::Backend>(std::make_unique<SlowBackend>(3000))
                         : node::makeCpuBackend(1);
    master::runRenderJob(comm, *backend, testVolume(), testTf(), {}, job);
  });
  ASSERT_TRUE(errors[0]);
  try {
    std::rethrow_exception(errors[0]);
  } catch (const master::MpiError& e) {
    EXPECT_NE(std::string(e.what()).find("2"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find("1 "), std::string::npos) << e.what();
  }
}

TEST(RenderJob, AgreeOnErrorsTellsEveryRankTheFirstFailure) {
  std::vector<std::string> verdicts(3);
  const auto errors = test::runRanks(3, [&](master::Communicator& comm) {
    verdicts[std::size_t(comm.rank())] =
        master::agreeOnErrors(comm, comm.rank() == 1 ? "volume.vwz: truncated" : "", 5000);
  });
  for (const auto& e : errors) EXPECT_FALSE(e);
  for (const auto& v : verdicts) EXPECT_EQ(v, "rank 1 (thread1): volume.vwz: truncated");
  test::runRanks(
      2, [&](master::Communicator& comm) { EXPECT_EQ(master::agreeOnErrors(comm, "", 5000), ""); });
}

TEST(RenderJob, FirstFrameRectsForADryRun) {
  auto job = testJob("", 1);
  const auto rects = master::firstFrameRects(job, 3);
  ASSERT_EQ(rects.size(), 3u);
  for (const auto& r : rects) EXPECT_EQ(r.size(), 1u);
  job.masterRenders = false;
  EXPECT_TRUE(master::firstFrameRects(job, 3)[0].empty());
  EXPECT_THROW(master::firstFrameRects(job, 1), std::invalid_argument);
}

// A rank that keeps no pixels renders a rectangle in bands of the tile codec's segment rows:
// they tile the rectangle exactly, top to bottom.
TEST(RenderJob, BandsTileTheRectangleInSegmentRows) {
  auto job = testJob("", 1);
  const voxwall::Rect rect{3, 5, 40, 50};
  EXPECT_EQ(master::bandRows(job), net::TileCodecSettings{}.segmentPixels);
  EXPECT_EQ(master::bands(rect, job), std::vector<voxwall::Rect>{rect});  // shorter than a band
  master::StreamSettings stream;
  stream.codec.segmentPixels = 16;
  job.stream = stream;
  const auto parts = master::bands(rect, job);
  ASSERT_EQ(parts.size(), 4u);
  int y = rect.y;
  for (const auto& p : parts) {
    EXPECT_EQ(p.x, rect.x);
    EXPECT_EQ(p.width, rect.width);
    EXPECT_EQ(p.y, y);
    EXPECT_EQ(p.height, std::min(16, rect.y + rect.height - y));
    y += p.height;
  }
  EXPECT_EQ(y, rect.y + rect.height);
}
