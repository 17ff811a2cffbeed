// `voxwall sink`'s options to the sink's settings, without starting a sink: defaults, every option
// that changes a setting, the values refused with the option's name; and the checks the commands
// share (master/src/commands/option_checks.hpp).
#include "commands/sink_settings.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "commands/option_checks.hpp"
#include "support/expect_refused.hpp"

using namespace voxwall;
using namespace voxwall::cli;

using test::expectRefused;

namespace {

SinkOptions ci2x2() {
  SinkOptions o;
  o.wall = std::string(VOXWALL_WALLS_DIR) + "/ci-2x2.json";
  return o;
}

}  // namespace

TEST(SinkSettings, Defaults) {
  const walls::SinkSettings s = sinkSettings(ci2x2());
  EXPECT_EQ(s.wall.displays.size(), 4u);
  EXPECT_EQ(s.listenHost, "127.0.0.1");
  EXPECT_EQ(s.listenPort, 7400);
  EXPECT_TRUE(s.outDir.empty());
  EXPECT_EQ(s.outFormat, walls::FrameFormat::Png);
  EXPECT_EQ(s.writeQueue, 8);
  EXPECT_EQ(s.maxFrames, 0);
  EXPECT_EQ(s.pendingFrames, 16);
  EXPECT_EQ(s.pendingBytes, 0u);
  EXPECT_EQ(s.maxPeers, 256);
  EXPECT_EQ(s.helloTimeoutMs, 5000);
  EXPECT_EQ(s.peerIdleMs, 30000);
  EXPECT_EQ(s.jobIdleMs, 300000);
  EXPECT_TRUE(s.httpHost.empty());
  EXPECT_EQ(s.maxViewers, 64);
  EXPECT_EQ(s.maxDisplayPages, 0);
  EXPECT_EQ(s.swapTimeoutMs, 500);
  EXPECT_EQ(s.swapLeadMs, 25);
  EXPECT_FALSE(s.mosaic);
  EXPECT_TRUE(s.token.empty());
}

TEST(SinkSettings, EveryOptionReachesItsSetting) {
  SinkOptions o = ci2x2();
  o.listen = "0.0.0.0:7500";
  o.out = "wall-frames";
  o.outFormat = "jpeg";
  o.writeQueue = 3;
  o.mosaic = true;
  o.token = "secret";
  o.frames = 40;
  o.pending = 4;
  o.pendingMiB = 128;
  o.maxPeers = 9;
  o.helloTimeoutMs = 700;
  o.peerIdle = 12.5;
  o.http = "127.0.0.1:8080";
  o.httpOrigins = {"https://wall.example.org"};
  o.maxViewers = 5;
  o.maxDisplayPages = 6;
  o.swapTimeoutMs = 250;
  o.swapLeadMs = 0;
  const walls::SinkSettings s = sinkSettings(o);
  EXPECT_EQ(s.listenHost, "0.0.0.0");
  EXPECT_EQ(s.listenPort, 7500);
  EXPECT_EQ(s.outDir, "wall-frames");
  EXPECT_EQ(s.outFormat, walls::FrameFormat::Jpeg);
  EXPECT_EQ(s.writeQueue, 3);
  EXPECT_TRUE(s.mosaic);
  EXPECT_EQ(s.token, "secret");
  EXPECT_EQ(s.maxFrames, 40);
  EXPECT_EQ(s.pendingFrames, 4);
  EXPECT_EQ(s.pendingBytes, 128ull << 20);
  EXPECT_EQ(s.maxPeers, 9);
  EXPECT_EQ(s.helloTimeoutMs, 700);
  EXPECT_EQ(s.peerIdleMs, 12500);
  EXPECT_EQ(s.httpHost, "127.0.0.1");
  EXPECT_EQ(s.httpPort, 8080);
  EXPECT_EQ(s.httpOrigins, o.httpOrigins);
  EXPECT_EQ(s.maxViewers, 5);
  EXPECT_EQ(s.maxDisplayPages, 6);
  EXPECT_EQ(s.swapTimeoutMs, 250);
  EXPECT_EQ(s.swapLeadMs, 0);
  o.outFormat = "jpg";
  EXPECT_EQ(sinkSettings(o).outFormat, walls::FrameFormat::Jpeg);
}

TEST(SinkSettings, ValuesOutsideTheirRangeAreRefusedNamingTheOption) {
  auto refused = [](auto change, const std::string& prefix) {
    SinkOptions o = ci2x2();
    change(o);
    expectRefused([&] { (void)sinkSettings(o); }, prefix);
  };
  refused([](SinkOptions& o) { o.writeQueue = 0; }, "--write-queue must be in [1, 1024]");
  refused([](SinkOptions& o) { o.frames = -1; }, "--frames must be in [0, 1073741824]");
  refused([](SinkOptions& o) { o.pending = 65; }, "--pending must be in [1, 64]");
  refused([](SinkOptions& o) { o.maxPeers = 0; }, "--max-peers must be in [1, 65536]");
  refused([](SinkOptions& o) { o.helloTimeoutMs = 600001; },
          "--hello-timeout-ms must be in [1, 600000]");
  refused([](SinkOptions& o) { o.peerIdle = 5; }, "--peer-idle 5: expected 10 to 86400 seconds");
  refused([](SinkOptions& o) { o.peerIdle = std::nan(""); }, "--peer-idle");
  refused([](SinkOptions& o) { o.jobIdle = 9; }, "--job-idle 9: expected 10 to 86400 seconds");
  refused([](SinkOptions& o) { o.pendingMiB = (1ull << 20) + 1; }, "--pending-mib is over 1 TiB");
  refused([](SinkOptions& o) { o.maxViewers = 4097; }, "--max-viewers must be in [1, 4096]");
  refused([](SinkOptions& o) { o.maxDisplayPages = -1; },
          "--max-display-pages must be in [0, 4096]");
  refused([](SinkOptions& o) { o.swapTimeoutMs = 0; }, "--swap-timeout must be in [1, 60000]");
  refused([](SinkOptions& o) { o.swapLeadMs = 1001; }, "--swap-lead must be in [0, 1000]");
  refused([](SinkOptions& o) { o.outFormat = "gif"; }, "--out-format: expected png, jpg or jpeg");
  refused([](SinkOptions& o) { o.listen = "nowhere"; }, "--listen");
  refused([](SinkOptions& o) { o.httpOrigins = {"https://a.example"}; },
          "--http-origin goes with --http");
  refused(
      [](SinkOptions& o) {
        o.http = "127.0.0.1:0";
        o.httpOrigins = {"wall.example.org"};
      },
      "--http-origin 'wall.example.org': expected http://HOST[:PORT]");
}

TEST(SinkSettings, AWallFileThatIsNotThereIsRefused) {
  SinkOptions o;
  o.wall = "/nonexistent/wall.json";
  EXPECT_ANY_THROW((void)sinkSettings(o));
}

TEST(OptionChecks, RangesSayTheirBoundsAsWritten) {
  EXPECT_EQ(inRange(5, 1, 10, "--x"), 5);
  EXPECT_EQ(inRange(0.5, 0.0, 1.0, "--y", "dB"), 0.5);
  expectRefused([] { (void)inRange(11, 1, 10, "--x"); }, "--x must be in [1, 10]");
  expectRefused([] { (void)inRange(2.5, 0.25, 2.0, "--y", "dB"); }, "--y must be in [0.25, 2] dB");
  expectRefused([] { (void)inRange(std::numeric_limits<double>::quiet_NaN(), 0.0, 1.0, "--z"); },
                "--z must be in [0, 1]");
  expectRefused([] { (void)inRange(-1, 0, 1 << 30, "--frames"); },
                "--frames must be in [0, 1073741824]");
}

TEST(OptionChecks, ChoicesAndSizes) {
  EXPECT_EQ(choose<int>("b", "--pick", {{"a", 1}, {"b", 2}, {"c", 3}}), 2);
  expectRefused(
      [] {
        (void)choose<int>("d", "--pick", {{"a", 1}, {"b", 2}, {"c", 3}});
      },
      "--pick: expected a, b or c");
  EXPECT_EQ(parseBytes("512M", "--memory-budget"), 512ull << 20);
  EXPECT_EQ(parseBytes("1.5GiB", "--memory-budget"), 3ull << 29);
  EXPECT_EQ(parseBytes("4096", "--memory-budget"), 4096u);
  expectRefused([] { (void)parseBytes("12Q", "--memory-budget"); }, "--memory-budget");
  expectRefused([] { (void)parseBytes("-1G", "--memory-budget"); }, "--memory-budget");
  EXPECT_EQ(parseBytesOrOff("off", "--decode-cache"), 0u);
  EXPECT_EQ(parseBytesOrOff("0", "--decode-cache"), 0u);
  EXPECT_EQ(parseBytesOrOff("2G", "--decode-cache"), 2ull << 30);
  expectRefused([] { (void)parseBytesOrOff("lots", "--decode-cache"); },
                "--decode-cache: expected a size such as 512M or 2G, or off");
}
