// `voxwall render`'s options to settings, without running anything: defaults, every option that
// changes a setting, and the combinations that are refused with the option's name.
#include "commands/render_settings.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "support/expect_refused.hpp"

using namespace voxwall;
using namespace voxwall::cli;

using test::expectRefused;

TEST(RenderSettings, Defaults) {
  const RenderOptions o;
  const auto job = jobSettings(o);
  EXPECT_EQ(job.width, 1920);
  EXPECT_EQ(job.height, 1080);
  EXPECT_EQ(job.frames, 1);
  EXPECT_EQ(job.balance, master::Balance::Dynamic);
  EXPECT_EQ(job.outDir, "frames");
  EXPECT_EQ(job.watchdogMs, 120000);
  EXPECT_TRUE(job.masterRenders);
  EXPECT_FALSE(job.stream);
  EXPECT_TRUE(job.background.has_value());
  const auto render = renderSettings(o);
  EXPECT_FLOAT_EQ(float(render.stepVoxels), 0.25f);
  EXPECT_FALSE(render.nearest);
  EXPECT_TRUE(render.emptySpaceSkipping);
  EXPECT_EQ(render.latticeStride, 0);  // the ray lattice, its stride picked per frame
  EXPECT_EQ(render.refineAboveLevels, 8);
  EXPECT_EQ(job.frameBudgetMs, 200);  // steered frames keep a budget
}

TEST(RenderSettings, TheLatticeExactAndTheFrameBudget) {
  RenderOptions o;
  o.lattice = "8";
  EXPECT_EQ(renderSettings(o).latticeStride, 8);
  o.exact = true;
  expectRefused([&] { (void)renderSettings(o); }, "--exact casts a ray a pixel");
  o.lattice = "auto";
  EXPECT_EQ(renderSettings(o).latticeStride, 1);
  o.exact = false;
  for (const char* bad : {"0", "3", "32", "four"}) {
    o.lattice = bad;
    expectRefused([&] { (void)renderSettings(o); }, "--lattice: expected auto or a power of two");
  }
  o.lattice = "auto";
  o.refineAbove = -1;
  expectRefused([&] { (void)renderSettings(o); }, "--refine-above must be in [0, 255]");
  // A step given alone keeps its fixed step; given with a budget, the budget picks.
  o.refineAbove = 8;
  o.interactiveStepGiven = true;
  EXPECT_EQ(jobSettings(o).frameBudgetMs, 0);
  o.frameBudgetGiven = true;
  o.frameBudgetMs = 150;
  EXPECT_EQ(jobSettings(o).frameBudgetMs, 150);
}

TEST(RenderSettings, ScreenFromSizeOrWallNotBoth) {
  RenderOptions o;
  o.size = "640x480";
  EXPECT_EQ(jobSettings(o).width, 640);
  o.wall = std::string(VOXWALL_WALLS_DIR) + "/ci-2x2.json";
  o.sizeGiven = true;
  expectRefused([&] { (void)jobSettings(o); }, "--size and --wall both set the screen");
  o.sizeGiven = false;
  const auto job = jobSettings(o);
  EXPECT_GT(job.width, 0);
  EXPECT_NE(job.width, 640);
  o.wall.clear();
  o.size = "70000x10";
  expectRefused([&] { (void)jobSettings(o); }, "--size");
}

TEST(RenderSettings, StreamingNeedsAWallAndWritesNoFramesUnlessAsked) {
  RenderOptions o;
  o.sink = "127.0.0.1:9";
  expectRefused([&] { (void)jobSettings(o); }, "--sink needs --wall");
  o.wall = std::string(VOXWALL_WALLS_DIR) + "/ci-2x2.json";
  auto job = jobSettings(o);
  ASSERT_TRUE(job.stream);
  EXPECT_EQ(job.stream->port, 9);
  EXPECT_EQ(job.outDir, "");
  o.outGiven = true;
  EXPECT_EQ(jobSettings(o).outDir, "frames");
  o.tileCodec = "png";
  expectRefused([&] { (void)jobSettings(o); }, "--tile-codec");
  o.tileCodec = "jpeg";
  o.subsampling = "411";
  expectRefused([&] { (void)jobSettings(o); }, "--subsampling");
  RenderOptions t;
  t.token = "secret";
  expectRefused([&] { (void)jobSettings(t); }, "--token goes with --sink");
}

TEST(RenderSettings, TilesCutStaticallyAndRefuseDynamic) {
  RenderOptions o;
  o.tiles = "3x2";
  auto job = jobSettings(o);
  EXPECT_EQ(job.balance, master::Balance::Static);
  EXPECT_EQ(job.staticTilesX, 3);
  EXPECT_EQ(job.staticTilesY, 2);
  o.balanceGiven = true;
  expectRefused([&] { (void)jobSettings(o); }, "--tiles cuts the screen statically");
  o.balance = "fair";
  expectRefused([&] { (void)jobSettings(o); }, "--balance");
}

TEST(RenderSettings, CameraFramesAndLimitsAreChecked) {
  RenderOptions o;
  o.camera = "30";
  expectRefused([&] { (void)jobSettings(o); }, "--camera");
  o.camera = "30,20,-1";
  expectRefused([&] { (void)jobSettings(o); }, "--camera: distance");
  o.camera = "30,20";
  o.frames = 0;
  expectRefused([&] { (void)jobSettings(o); }, "--frames");
  o.frames = 8;
  o.fov = 180;
  expectRefused([&] { (void)jobSettings(o); }, "--fov");
  o.fov = 30;
  o.watchdogSeconds = 0.5;
  expectRefused([&] { (void)jobSettings(o); }, "--watchdog");
  o.watchdogSeconds = 3;
  o.costCell = 2;
  expectRefused([&] { (void)jobSettings(o); }, "--cost-cell");
  o.costCell = 16;
  o.resume = true;
  o.noWrite = true;
  expectRefused([&] { (void)jobSettings(o); }, "--resume needs frames on disk");
  o.noWrite = false;
  const auto job = jobSettings(o);
  EXPECT_EQ(job.frames, 8);
  EXPECT_EQ(job.watchdogMs, 3000);
  EXPECT_EQ(job.balancer.cellPixels, 16);
  EXPECT_TRUE(job.resume);
}

TEST(RenderSettings, RendererOptions) {
  RenderOptions o;
  {  // By default the march comes from the error budget, at points or pre-integrated.
    const auto r = renderSettings(o);
    EXPECT_EQ(r.errorBudgetDb, node::kDefaultErrorBudgetDb);
    EXPECT_EQ(r.marchIntegration, node::MarchIntegration::Either);
    o.exact = true;  // --exact: a quarter voxel at points, no budget
    const auto exact = renderSettings(o);
    EXPECT_EQ(exact.errorBudgetDb, 0.0);
    EXPECT_EQ(exact.stepVoxels, 0.25);
    EXPECT_EQ(exact.marchIntegration, node::MarchIntegration::Point);
    EXPECT_FALSE(exact.preIntegrate);
    o.integration = "pre";
    expectRefused([&] { (void)renderSettings(o); }, "--exact samples the transfer function");
    o.exact = false;
    o.errorBudget = 95;
    expectRefused([&] { (void)renderSettings(o); }, "--error-budget");
    o.errorBudget = 45;
    EXPECT_EQ(renderSettings(o).marchIntegration, node::MarchIntegration::Pre);
    o.integration = "linear";
    expectRefused([&] { (void)renderSettings(o); }, "--integration");
    o.integration = "auto";
  }
  for (const char* bad : {"0", "9", "half", "0.5x", ""}) {
    o.step = bad;
    expectRefused([&] { (void)renderSettings(o); }, "--step");
  }
  o.step = "0.5";
  {  // A step given is the step: no budget, at points unless asked.
    const auto r = renderSettings(o);
    EXPECT_EQ(r.errorBudgetDb, 0.0);
    EXPECT_FALSE(r.preIntegrate);
  }
  o.sampling = "cubic";
  expectRefused([&] { (void)renderSettings(o); }, "--sampling");
  o.sampling = "nearest";
  o.shading = o.noSkip = o.lod = true;
  const auto r = renderSettings(o);
  EXPECT_TRUE(r.nearest && r.shading && r.levelOfDetail && !r.emptySpaceSkipping);
  EXPECT_FLOAT_EQ(float(r.stepVoxels), 0.5f);
}

// --backend, --threads, --simd, --decode-cache, --device-decode and --memory-budget, read once.
TEST(RenderSettings, TheBackendIsReadOnce) {
  RenderOptions o;
  {
    const BackendSettings b = backendSettings(o);
    EXPECT_EQ(b.kind, node::BackendKind::Cpu);
    EXPECT_EQ(b.threads, 0);
    EXPECT_TRUE(b.simd);
    EXPECT_EQ(b.decodeCacheBytes, 512ull << 20);
    EXPECT_EQ(b.deviceDecode, node::DeviceDecode::Whole);
    EXPECT_FALSE(b.memoryBudgetBytes);
    EXPECT_TRUE(b.decodesPages());
  }
  o.backend = "opengl";
  expectRefused([&] { (void)backendSettings(o); }, "--backend: expected cpu or cuda");
  o.backend = "cuda";
  o.deviceDecode = "lazy";
  expectRefused([&] { (void)backendSettings(o); }, "--device-decode: expected whole or per-ray");
  o.deviceDecode = "per-ray";
  o.threads = 3;
  o.memoryBudget = "2G";
  {  // both are read on any machine; the device is found later
    const BackendSettings b = backendSettings(o);
    EXPECT_EQ(b.kind, node::BackendKind::Cuda);
    EXPECT_EQ(b.deviceDecode, node::DeviceDecode::PerRay);
    EXPECT_EQ(b.threads, 3);
    EXPECT_EQ(b.memoryBudgetBytes, 2ull << 30);
    EXPECT_FALSE(b.decodesPages());  // pages are the CPU's
  }
  o.backend = "cpu";
  o.simd = "off";
  EXPECT_FALSE(backendSettings(o).decodesPages());
  o.simd = "maybe";
  expectRefused([&] { (void)backendSettings(o); }, "--simd: expected on or off");
  o.simd = "on";
  o.decodeCache = "off";
  EXPECT_FALSE(backendSettings(o).decodesPages());
  o.decodeCache = "lots";
  expectRefused([&] { (void)backendSettings(o); }, "--decode-cache: expected a size");
  o.decodeCache = "1G";
  o.threads = -2;
  expectRefused([&] { (void)backendSettings(o); }, "--threads must be in [0, 4096]");
  o.threads = 0;
  o.memoryBudget = "much";
  expectRefused([&] { (void)backendSettings(o); }, "--memory-budget");
}

TEST(RenderSettings, BackgroundsAndRects) {
  EXPECT_FALSE(parseBackground("none"));
  EXPECT_EQ(*parseBackground("white"), glm::dvec3(1.0));
  EXPECT_EQ(*parseBackground("0.5,0.25,0"), glm::dvec3(0.5, 0.25, 0));
  expectRefused([] { (void)parseBackground("2,0,0"); }, "--background");
  EXPECT_EQ(rectList({{0, 0, 4, 3}, {4, 0, 2, 3}}), " 4x3+0+0 2x3+4+0");
}

TEST(RenderSettings, RankZeroNeedsMoreMemoryForTheFrame) {
  RenderOptions o;
  const auto job = jobSettings(o);
  const auto zero = estimateRankBytes(job, 0, 2, 1 << 20, 0);
  const auto one = estimateRankBytes(job, 1, 2, 1 << 20, 0);
  EXPECT_GT(zero, one);
  EXPECT_GT(one, std::uint64_t(1) << 20);
  // Streaming to a sink without --out: rank 0 gathers no pixels, so it needs no screen-sized
  // buffers beyond its own part (the cost grids are all it receives).
  o.sink = "127.0.0.1:9";
  o.wall = std::string(VOXWALL_WALLS_DIR) + "/ci-2x2.json";
  const auto streaming = jobSettings(o);
  ASSERT_EQ(streaming.outDir, "");
  const auto screen = std::uint64_t(streaming.width) * std::uint64_t(streaming.height);
  const auto zeroStreaming = estimateRankBytes(streaming, 0, 2, 1 << 20, 0);
  const auto oneStreaming = estimateRankBytes(streaming, 1, 2, 1 << 20, 0);
  EXPECT_LT(zeroStreaming - oneStreaming, screen);
  o.outGiven = true;  // frames written too: rank 0 assembles them
  EXPECT_GT(estimateRankBytes(jobSettings(o), 0, 2, 1 << 20, 0) - oneStreaming, 8 * screen);
}

// A streaming rank holds one band of pixels, not what the balancer may give it: on a wall far
// taller than a band, its need is the band's (8 bytes a pixel: picture and encoded tiles), while
// a rank whose frames are written holds the whole screen under a dynamic cut.
TEST(RenderSettings, AStreamingRankNeedsOneBandOfPixels) {
  master::JobSettings job;
  job.width = 5760, job.height = 4320;
  master::StreamSettings stream;
  job.stream = stream;
  const std::uint64_t volume = 1 << 20;
  const auto band = std::uint64_t(job.width) * std::uint64_t(master::bandRows(job)) * 8;
  const auto screen = std::uint64_t(job.width) * std::uint64_t(job.height) * 8;
  for (int rank = 0; rank < 6; ++rank) {
    const auto need = estimateRankBytes(job, rank, 6, volume, 0);
    EXPECT_GE(need, volume + band) << "rank " << rank;
    EXPECT_LT(need, volume + band + (8u << 20)) << "rank " << rank;
  }
  job.balance = master::Balance::Static;  // strips of 720 rows: shorter than a band
  EXPECT_LT(estimateRankBytes(job, 1, 6, volume, 0), volume + job.width * 720 * 8 + (8u << 20));
  job.balance = master::Balance::Dynamic;
  job.stream.reset();
  job.outDir = "frames";
  EXPECT_GT(estimateRankBytes(job, 1, 6, volume, 0), volume + screen);
}

// A codec's render flags (tvq's --progressive) change the picture: the resume manifest records
// them, so --resume does not mix frames of two progressive levels.
TEST(RenderSettings, ManifestRecordsTheCodecRenderFlags) {
  RenderOptions o;
  const auto job = jobSettings(o);
  const auto render = renderSettings(o);
  const std::string plain = manifest(o, job, render, 1);
  EXPECT_EQ(plain.find("codec_options"), std::string::npos);
  o.codecFlags["--progressive"] = "dc";
  const std::string dc = manifest(o, job, render, 1);
  EXPECT_NE(dc.find("\"--progressive\":\"dc\""), std::string::npos) << dc;
  o.codecFlags["--progressive"] = "lp";
  EXPECT_NE(manifest(o, job, render, 1), dc);
  EXPECT_EQ(codecRenderOptions(o).text("--progressive", ""), "lp");
}

// --path still: frame 0's camera for every frame, so the camera moves only when steered.
TEST(RenderSettings, AStillPathKeepsTheCamera) {
  RenderOptions o;
  o.path = "still";
  o.frames = 50;
  o.camera = "40,10,3";
  const auto job = jobSettings(o);
  EXPECT_EQ(job.path.at(0).azimuthDeg, 40);
  EXPECT_EQ(job.path.at(49).azimuthDeg, 40);
  EXPECT_EQ(job.path.at(49).distance, 3);
  o.path = "orbit";
  EXPECT_NE(jobSettings(o).path.at(49).azimuthDeg, 40);
}

// --time: a range of steps, one step, all; a step a frame, or each step for several frames.
TEST(RenderSettings, TimeRangesMapFramesToSteps) {
  RenderOptions o;
  o.time = "2:8:3";
  master::TimeSettings t = timeSettings(o, 10);
  EXPECT_EQ(t.count(), 3);  // 2, 5, 8
  EXPECT_EQ(t.stepOfFrame(0, 3), 2);
  EXPECT_EQ(t.stepOfFrame(2, 3), 8);
  // Seven frames of three steps: two frames a step, the last step to the end.
  const int want[7] = {2, 2, 5, 5, 8, 8, 8};
  for (int f = 0; f < 7; ++f) EXPECT_EQ(t.stepOfFrame(f, 7), want[f]) << f;
  EXPECT_EQ(t.stepAt(4), 5);  // playing loops
  o.time = "2:9:3";           // the last step a stride does not reach is dropped
  EXPECT_EQ(timeSettings(o, 10).last, 8);
  o.time = "all";
  EXPECT_EQ(timeSettings(o, 10).count(), 10);
  o.time = "4";
  t = timeSettings(o, 10);
  EXPECT_EQ(t.first, 4);
  EXPECT_EQ(t.stepOfFrame(5, 9), 4);
  o.time = "";
  o.timeRate = 2;  // playing without --time: every step
  EXPECT_EQ(timeSettings(o, 10).count(), 10);
  o.timeRate = 0;
  EXPECT_EQ(timeSettings(o, 10).count(), 1);  // step 0 alone
  for (const char* bad : {"1:", ":3", "a:b", "3:1", "0:3:0", "0:10", "1:2:3:4", "-1"}) {
    o.time = bad;
    EXPECT_THROW(timeSettings(o, 10), std::invalid_argument) << bad;
  }
}

TEST(RenderSettings, TheTransferFunctionsOptionsAreReadOnce) {
  RenderOptions o;
  auto t = transferSettings(o);
  EXPECT_EQ(t.map, "mri");
  EXPECT_FALSE(t.range.has_value());
  EXPECT_EQ(t.slope, 1);
  EXPECT_EQ(t.intercept, 0);
  EXPECT_FALSE(t.perStep);
  o.tf = "hu-bone";
  o.opacity = "grey";
  o.window = "400,1800";
  o.rescale = "1,-1024";
  o.range = "per-step";
  t = transferSettings(o);
  EXPECT_EQ(t.map, "hu-bone");
  EXPECT_EQ(t.opacity, "grey");
  ASSERT_TRUE(t.range.has_value());
  EXPECT_EQ(t.range->first, -500);
  EXPECT_EQ(t.range->second, 1300);
  EXPECT_EQ(t.slope, 1);
  EXPECT_EQ(t.intercept, -1024);
  EXPECT_TRUE(t.perStep);
  o.window.clear();
  o.tfRange = "10,20";
  EXPECT_EQ(transferSettings(o).range, (std::pair{10.0, 20.0}));
  const auto refused = [&](auto change, const std::string& why) {
    RenderOptions bad;
    change(bad);
    expectRefused([&] { (void)transferSettings(bad); }, why);
  };
  refused([](RenderOptions& b) { b.tfRange = "20,10"; }, "--tf-range: expected LO,HI with LO < HI");
  refused([](RenderOptions& b) { b.window = "40,0"; },
          "--window: expected CENTER,WIDTH with WIDTH > 0");
  refused([](RenderOptions& b) { b.rescale = "0,5"; },
          "--rescale: expected SLOPE,INTERCEPT with SLOPE > 0");
  refused([](RenderOptions& b) { b.range = "each"; }, "--range: expected series or per-step");
}
