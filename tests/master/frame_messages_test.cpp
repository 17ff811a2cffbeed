#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <voxwall/core/errors.hpp>
#include <voxwall/master/frame_messages.hpp>

using namespace voxwall;

namespace {

master::FrameTask sampleTask() {
  master::FrameTask t;
  t.frame = 7;
  t.camera.eye = {1, -2, 3};
  t.camera.fovYDeg = 40;
  t.watchdogMs = 5000;
  t.screenWidth = 64, t.screenHeight = 48;
  t.cellPixels = 16;
  t.jobId = 0xfeedf00d12345678ull;
  t.step = 2;
  t.phase = net::FramePhase::Refining;
  t.rects = {{{0, 0, 32, 48}}, {{32, 0, 32, 20}, {32, 20, 32, 28}}, {}};
  return t;
}

master::RankReport sampleReport(const master::FrameTask& t) {
  master::RankReport r;
  r.frame = t.frame;
  r.rank = 1;
  r.renderSeconds = 0.25;
  r.samples = 12345;
  r.rays = 678, r.latticeStride = 4;
  r.residentBytes = 1 << 20, r.peakResidentBytes = 2 << 20;
  r.privateBytes = 3 << 18, r.fileBytes = 1 << 18, r.sharedBytes = 5 << 16;
  r.pages = {1000, 20, 3, 2, 5 << 20, 17, 9};
  for (const auto& rect : t.rects[1]) {
    master::RenderedTile tile{rect, voxwall::Image(rect.width, rect.height)};
    for (std::size_t i = 0; i < tile.image.pixels.size(); ++i)
      tile.image.pixels[i] = std::uint32_t(i * 2654435761u);
    r.tiles.push_back(tile);
  }
  r.costs = node::CostGrid(t.screenWidth, t.screenHeight, t.cellPixels);
  r.costs.add({32, 0, 32, 48}, 0.25);
  r.streamed = false;
  r.streamRefused = true;
  r.streamError = "sink 127.0.0.1:7400: refused: wrong token";
  r.abandoned = true;
  return r;
}

void expectRejected(std::span<const std::byte> bytes, const master::FrameTask* task) {
  if (task)
    EXPECT_THROW(master::decodeRankReport(bytes, *task, "test"), FormatError);
  else
    EXPECT_THROW(master::decodeFrameTask(bytes, "test"), FormatError);
}

template <typename T>
void poke(std::vector<std::byte>& bytes, std::size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof value);
}

}  // namespace

TEST(FrameTask, RoundTrips) {
  const auto t = sampleTask();
  const auto back = master::decodeFrameTask(master::encode(t), "test");
  EXPECT_EQ(back.frame, 7u);
  EXPECT_FALSE(back.stop);
  EXPECT_EQ(back.camera.eye, t.camera.eye);
  EXPECT_EQ(back.camera.fovYDeg, 40);
  EXPECT_EQ(back.watchdogMs, 5000u);
  EXPECT_EQ(back.jobId, 0xfeedf00d12345678ull);
  EXPECT_EQ(back.cellPixels, 16);
  EXPECT_EQ(back.step, 2);
  EXPECT_EQ(back.phase, net::FramePhase::Refining);
  EXPECT_EQ(back.rects, t.rects);
  auto steered = t;
  steered.phase = net::FramePhase::Interactive;
  EXPECT_EQ(master::decodeFrameTask(master::encode(steered), "test").phase,
            net::FramePhase::Interactive);
  auto bytes = master::encode(t);
  poke<std::uint32_t>(bytes, 12, 6u);  // interactive and refining at once
  expectRejected(bytes, nullptr);
}

TEST(FrameTask, RejectsAStepOutOfRange) {
  for (const int step : {0, -1, master::kMaxTaskStep + 1}) {
    auto t = sampleTask();
    t.step = step;
    try {
      master::decodeFrameTask(master::encode(t), "task");
      ADD_FAILURE() << "step " << step << " accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("step"), std::string::npos) << e.what();
    }
  }
}

TEST(FrameTask, RejectsEveryTruncation) {
  const auto bytes = master::encode(sampleTask());
  for (std::size_t n = 0; n < bytes.size(); ++n) expectRejected(std::span(bytes).first(n), nullptr);
}

TEST(FrameTask, RejectsOtherVersionsAndMagic) {
  for (std::uint32_t version :
       {0u, master::kFrameMessageVersion - 1, master::kFrameMessageVersion + 1}) {
    if (version == master::kFrameMessageVersion) continue;
    auto bytes = master::encode(sampleTask());
    poke(bytes, 4, version);
    try {
      master::decodeFrameTask(bytes, "rank 0");
      FAIL() << "version " << version << " accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("version"), std::string::npos) << e.what();
    }
  }
  auto bytes = master::encode(sampleTask());
  poke(bytes, 0, std::uint32_t(0xdeadbeef));
  expectRejected(bytes, nullptr);
}

TEST(FrameTask, RejectsRectanglesOffTheScreenAndHugeCounts) {
  auto t = sampleTask();
  t.rects[0][0].width = 33;  // 32 + 33 > 64
  t.rects[0][0].x = 32;
  expectRejected(master::encode(t), nullptr);
  t = sampleTask();
  t.rects[0][0].height = 0;
  expectRejected(master::encode(t), nullptr);
  // Rank count and rect count fields set to huge values.
  auto bytes = master::encode(sampleTask());
  const std::size_t rankCountAt = 4 * 4 + 8 + 10 * 8 + 4 * 2 + 4 * 3;
  poke(bytes, rankCountAt, std::uint32_t(0xffffffff));
  expectRejected(bytes, nullptr);
  bytes = master::encode(sampleTask());
  poke(bytes, rankCountAt + 4, std::uint32_t(1u << 30));
  expectRejected(bytes, nullptr);
  // A non-finite camera.
  t = sampleTask();
  t.camera.eye.x = std::nan("");
  expectRejected(master::encode(t), nullptr);
}

TEST(FrameTask, SurvivesRandomCorruption) {
  const auto good = master::encode(sampleTask());
  std::mt19937 rng(7);
  for (int trial = 0; trial < 2000; ++trial) {
    auto bytes = good;
    for (int k = 0; k < 3; ++k) bytes[rng() % bytes.size()] = std::byte(rng());
    try {
      const auto t = master::decodeFrameTask(bytes, "test");
      for (const auto& rects : t.rects)
        for (const auto& r : rects) {
          EXPECT_GE(r.x, 0);
          EXPECT_LE(r.x + r.width, t.screenWidth);
          EXPECT_LE(r.y + r.height, t.screenHeight);
        }
    } catch (const FormatError&) {
    }
  }
}

TEST(RankReport, RoundTrips) {
  const auto t = sampleTask();
  const auto r = sampleReport(t);
  const auto back = master::decodeRankReport(master::encode(r), t, "test");
  EXPECT_EQ(back.rank, 1);
  EXPECT_EQ(back.renderSeconds, 0.25);
  EXPECT_EQ(back.samples, 12345u);
  EXPECT_EQ(back.rays, 678u);
  EXPECT_EQ(back.latticeStride, 4);
  EXPECT_EQ(back.peakResidentBytes, 2u << 20);
  EXPECT_EQ(back.pages.hits, 1000u);
  EXPECT_EQ(back.pages.missed, 20u);
  EXPECT_EQ(back.pages.decoded, 3u);
  EXPECT_EQ(back.pages.evictions, 2u);
  EXPECT_EQ(back.pages.residentBytes, 5u << 20);
  EXPECT_EQ(back.pages.coarse, 17u);
  EXPECT_EQ(back.pages.waited, 9u);
  EXPECT_EQ(back.privateBytes, 3u << 18);
  EXPECT_EQ(back.fileBytes, 1u << 18);
  EXPECT_EQ(back.sharedBytes, 5u << 16);
  ASSERT_EQ(back.tiles.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back.tiles[i].rect, r.tiles[i].rect);
    EXPECT_EQ(back.tiles[i].image.pixels, r.tiles[i].image.pixels);
  }
  EXPECT_EQ(back.costs.seconds, r.costs.seconds);
  EXPECT_FALSE(back.streamed);
  EXPECT_TRUE(back.streamRefused);
  EXPECT_EQ(back.streamError, r.streamError);
  EXPECT_TRUE(back.abandoned);
  EXPECT_NEAR(back.costs.total(), 0.25, 1e-12);
}

// A rank that streamed its tiles (or was not asked for pixels) reports rectangles only: the
// decoded tiles have no pixels, and the master pastes none (found by fuzz.frame_messages, whose
// check had assumed every tile carries its pixels).
TEST(RankReport, WithoutPixelsCarriesRectanglesOnly) {
  const auto t = sampleTask();
  auto r = sampleReport(t);
  r.pixels = false, r.streamed = true;
  const auto bytes = master::encode(r);
  EXPECT_EQ(bytes.size(), master::encode(sampleReport(t)).size() - 32 * 48 * 4);
  const auto back = master::decodeRankReport(bytes, t, "test");
  EXPECT_FALSE(back.pixels);
  EXPECT_TRUE(back.streamed);
  ASSERT_EQ(back.tiles.size(), r.tiles.size());
  for (std::size_t i = 0; i < back.tiles.size(); ++i) {
    EXPECT_EQ(back.tiles[i].rect, r.tiles[i].rect);
    EXPECT_TRUE(back.tiles[i].image.pixels.empty());
  }
}

TEST(RankReport, RejectsTruncationWrongFrameAndMismatchedGrid) {
  const auto t = sampleTask();
  const auto bytes = master::encode(sampleReport(t));
  for (std::size_t n = 0; n < bytes.size(); n += 7) expectRejected(std::span(bytes).first(n), &t);
  auto other = t;
  other.frame = 8;
  expectRejected(bytes, &other);
  auto smaller = t;
  smaller.cellPixels = 32;  // the grid no longer matches
  expectRejected(bytes, &smaller);
  auto narrow = t;
  narrow.screenWidth = 40;  // the tiles are off this screen
  expectRejected(bytes, &narrow);
  auto extra = bytes;
  extra.push_back(std::byte{0});
  expectRejected(extra, &t);
  // A stream error longer than the limit (its u16 length follows 168 bytes of fields).
  auto longError = bytes;
  const std::uint16_t huge = 60000;
  std::memcpy(longError.data() + 168, &huge, 2);
  expectRejected(longError, &t);
  // A ray lattice of negative stride (the i32 after 136 bytes of fields and the u64 of rays).
  auto negative = bytes;
  const std::int32_t minusOne = -1;
  std::memcpy(negative.data() + 144, &minusOne, 4);
  expectRejected(negative, &t);
}

// The next frame's camera and time step (for decoding ahead) travel when set, and are checked
// as the frame's own are.
TEST(FrameTask, TheNextFramesCameraAndTimeStepRoundTripAndAreChecked) {
  auto t = sampleTask();
  EXPECT_FALSE(master::decodeFrameTask(master::encode(t), "test").ahead);
  t.ahead = true;
  t.aheadCamera.eye = {4, 5, -6};
  t.aheadCamera.fovYDeg = 35;
  t.aheadTimeStep = 3;
  const auto back = master::decodeFrameTask(master::encode(t), "test");
  EXPECT_TRUE(back.ahead);
  EXPECT_EQ(back.aheadCamera.eye, t.aheadCamera.eye);
  EXPECT_EQ(back.aheadCamera.fovYDeg, 35.0);
  EXPECT_EQ(back.aheadTimeStep, 3u);
  EXPECT_EQ(back.rects, t.rects);
  auto bad = t;
  bad.aheadCamera.center.x = std::nan("");
  expectRejected(master::encode(bad), nullptr);
  bad = t;
  bad.aheadCamera.fovYDeg = 0;
  expectRejected(master::encode(bad), nullptr);
  bad = t;
  bad.aheadTimeStep = 1u << 30;
  expectRejected(master::encode(bad), nullptr);
  const auto bytes = master::encode(t);
  for (std::size_t n = 0; n < bytes.size(); n += 5)
    expectRejected(std::span(bytes).first(n), nullptr);
}
