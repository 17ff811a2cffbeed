// The displays' pages of `voxwall sink --http` against WebSocket clients that play the pages on
// loopback: the pages and the display list are served, a page gets its display's segments as the
// rank sent them, and the swap barrier over real sockets (a page that never answers leaves after
// the timeout, the others keep switching, a page that catches up rejoins). The real browser test
// is tests/web/display_pages_test.py.
#include <gtest/gtest.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/walls/web_view.hpp>

#include "support/sink_runner.hpp"
#include "support/web_clients.hpp"

using namespace voxwall;
using namespace voxwall::test;

namespace {

// A display page played by a test: reads the sink's messages, answers when told to.
class Page {
 public:
  // `from`: the local address to connect from (127.0.0.2 is another loopback client).
  Page(std::uint16_t port, const std::string& display, const std::string& from = "")
      : viewer_(port, "", "/ws/display/" + display, from) {
    if (!viewer_.open()) return;
    info_ = nlohmann::json::parse(viewer_.read());
  }
  bool open() const { return viewer_.open() && info_.is_object(); }
  const nlohmann::json& info() const { return info_; }
  // The next frame message: its JSON and the segments' bytes after it.
  nlohmann::json frame(std::string* bytes = nullptr) {
    for (int i = 0; i < 20; ++i) {
      bool binary = false;
      const auto m = viewer_.read(&binary);
      if (m.empty()) return nullptr;
      if (!binary) {
        notes_.push_back(nlohmann::json::parse(m));
        continue;
      }
      std::uint32_t n = 0;
      std::memcpy(&n, m.data(), 4);
      if (bytes) *bytes = m.substr(4 + n);
      return nlohmann::json::parse(m.substr(4, n));
    }
    return nullptr;
  }
  // Waits for {"type":"show"} of `seq` (notes read earlier count); false when none comes.
  bool shown(std::uint64_t seq) {
    for (int i = 0; i < 20; ++i) {
      for (const auto& n : notes_)
        if (n["type"] == "show" && n["seq"] == seq) return true;
      bool binary = false;
      const auto m = viewer_.read(&binary);
      if (m.empty()) return false;
      if (!binary) notes_.push_back(nlohmann::json::parse(m));
    }
    return false;
  }
  void say(const std::string& text) { viewer_.send(text); }
  const std::vector<nlohmann::json>& notes() const { return notes_; }  // text messages read

 private:
  Viewer viewer_;
  nlohmann::json info_;
  std::vector<nlohmann::json> notes_;
};

// Sends one frame of the 44x10 two-display wall as a rank would: cut at the display edges.
void sendFrame(net::Connection& c, std::uint64_t frame, std::uint32_t colour) {
  voxwall::Image screen(44, 10);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 44; ++x) screen.at(x, y) = 0xff000000u | colour | std::uint32_t(x << 16);
  net::TileCodecSettings s;
  s.codec = net::TileCodec::Raw;
  for (const auto& t : net::encodeTiles(screen, {0, 0, 44, 10}, {0, 0, 0}, s, c.welcome().cut()))
    c.send(net::encodeMessage(frame, net::TileMessage{t.rect, t.codec, 0, t.bytes}));
}

std::unique_ptr<net::Connection> rank(std::uint16_t port, const std::string& token = "") {
  return net::Connection::open("127.0.0.1", port,
                               net::Hello{net::Role::Renderer, 0, 1, "t2x1", token}, 2000);
}

}  // namespace

namespace {

// The time a page says it showed a frame at: now, in Unix milliseconds.
std::string nowMs() {
  return std::to_string(
      std::chrono::duration<double, std::milli>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}

}  // namespace

TEST(DisplayPages, ThePagesAndTheListWithLaunchLinesAreServed) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  const auto [status, body] = get(port, "/display/r0c1");
  EXPECT_EQ(status, 200);
  EXPECT_EQ(body, walls::displayPage());
  EXPECT_EQ(get(port, "/display/r9c9").first, 404);
  EXPECT_EQ(get(port, "/display/").first, 404);
  const auto [listed, html] = get(port, "/displays", http::verb::get, 0, "wallhost:8080");
  EXPECT_EQ(listed, 403);  // a name that is not loopback, served on loopback
  const auto list = get(port, "/displays").second;
  const std::string base = "http://127.0.0.1:" + std::to_string(port);
  EXPECT_NE(list.find("chromium --kiosk --user-data-dir=/tmp/voxwall-display-r0c1 --app=" + base +
                      "/display/r0c1"),
            std::string::npos)
      << list;
  const auto json = nlohmann::json::parse(get(port, "/displays.json").second);
  ASSERT_EQ(json["displays"].size(), 2u);
  EXPECT_EQ(json["displays"][1]["name"], "r0c1");
  EXPECT_EQ(json["displays"][1]["x"], 24);
  EXPECT_EQ(json["displays"][1]["url"], base + "/display/r0c1");
  // A display page's WebSocket for a display the wall does not have is refused.
  EXPECT_FALSE(Viewer(port, "", "/ws/display/nope").open());
  Page page(port, "r0c1");
  ASSERT_TRUE(page.open());
  EXPECT_EQ(page.info()["type"], "display");
  EXPECT_EQ(page.info()["w"], 20);
  EXPECT_EQ(page.info()["swap_timeout_ms"], 500);
}

// A page that says an implausible time (1e308 once made a 300-digit spread) or none does not
// forge or silence the swap log: the line counts it and spreads the times that are plausible.
TEST(DisplayPages, TheSwapLogUsesOnlyPlausibleShownTimes) {
  test::SinkRunner sink(webSink());
  Page left(sink.sink().httpPort(), "r0c0"), right(sink.sink().httpPort(), "r0c1");
  ASSERT_TRUE(left.open());
  ASSERT_TRUE(right.open());
  auto r = rank(sink.port());
  sendFrame(*r, 0, 0x40);
  const auto seqOf = [](Page& page) {
    const auto meta = page.frame(nullptr);
    return meta.is_null() ? std::uint64_t(0) : meta["seq"].get<std::uint64_t>();
  };
  const std::uint64_t seq = seqOf(left);
  ASSERT_EQ(seqOf(right), seq);
  for (Page* page : {&left, &right}) page->say("ready " + std::to_string(seq));
  ASSERT_TRUE(left.shown(seq));
  ASSERT_TRUE(right.shown(seq));
  left.say("shown " + std::to_string(seq) + " " + nowMs());
  right.say("shown " + std::to_string(seq) + " 1e308");
  EXPECT_TRUE(sink.waitFor([&](const walls::SinkStats&) {
    return sink.log().find(
               "frame 0 shown together on 2 display page(s), spread 0.0 ms, from "
               "the times of 1 (1 said none or an implausible one)") != std::string::npos;
  })) << sink.log();
  // The right page now says nothing at all: each frame is still reported, 16 frames later.
  for (std::uint64_t f = 1; f <= 17; ++f) {
    sendFrame(*r, f, 0x40);
    const std::uint64_t next = seqOf(left);
    ASSERT_EQ(seqOf(right), next);
    for (Page* page : {&left, &right}) page->say("ready " + std::to_string(next));
    ASSERT_TRUE(left.shown(next));
    ASSERT_TRUE(right.shown(next));
    left.say("shown " + std::to_string(next) + " " + nowMs());
  }
  EXPECT_TRUE(sink.waitFor([&](const walls::SinkStats&) {
    return sink.log().find(
               "frame 1 shown together on 2 display page(s), spread 0.0 ms, from "
               "the times of 1") != std::string::npos;
  })) << sink.log();
}

TEST(DisplayPages, APageGetsItsDisplaysSegmentsAsTheRankSentThem) {
  test::SinkRunner sink(webSink());
  Page right(sink.sink().httpPort(), "r0c1");
  ASSERT_TRUE(right.open());
  auto r = rank(sink.port());
  sendFrame(*r, 0, 0x40);
  std::string bytes;
  const auto meta = right.frame(&bytes);
  ASSERT_FALSE(meta.is_null());
  EXPECT_EQ(meta["frame"], 0);
  ASSERT_EQ(meta["segments"].size(), 1u);  // the left display's segment is not sent here
  const auto& seg = meta["segments"][0];
  EXPECT_EQ(seg["x"], 24);
  EXPECT_EQ(seg["w"], 20);
  EXPECT_EQ(seg["codec"], "raw");
  ASSERT_EQ(bytes.size(), std::size_t(20 * 10 * 3));
  // The bytes are the rank's: row 0, column 24 of the screen.
  EXPECT_EQ(std::uint8_t(bytes[0]), 0x40);
  EXPECT_EQ(std::uint8_t(bytes[2]), 24);
  const auto seq = meta["seq"].get<std::uint64_t>();
  right.say("ready " + std::to_string(seq));
  EXPECT_TRUE(right.shown(seq));
  right.say("shown " + std::to_string(seq) + " " + nowMs());
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesSwapped >= 1; }));
  ASSERT_TRUE(sink.waitFor([&](const walls::SinkStats&) {
    return sink.log().find("frame 0 shown together on 1 display page(s), spread 0.0 ms") !=
           std::string::npos;
  })) << sink.log();
  // What a page may say is narrow: anything else closes it, and reaches the log only quoted (a
  // newline there once forged a log line).
  right.say("rotate 10 0\nframe 999999 presented: forged");
  Page again(sink.sink().httpPort(), "r0c1");
  EXPECT_TRUE(again.open());
  EXPECT_TRUE(sink.waitFor([&](const walls::SinkStats&) {
    return sink.log().find("not a display page's message: \"rotate 10 0\\x0aframe") !=
           std::string::npos;
  })) << sink.log();
  EXPECT_EQ(sink.log().find("\nframe 999999"), std::string::npos) << sink.log();
}

TEST(DisplayPages, APageThatNeverAnswersLeavesTheBarrierTheOtherKeepsSwitchingAndItRejoins) {
  auto settings = webSink();
  settings.swapTimeoutMs = 300;
  test::SinkRunner sink(settings);
  Page left(sink.sink().httpPort(), "r0c0"), right(sink.sink().httpPort(), "r0c1");
  ASSERT_TRUE(left.open() && right.open());
  auto r = rank(sink.port());
  auto readyBoth = [&](std::uint64_t frame) {
    const auto a = left.frame(), b = right.frame();
    EXPECT_EQ(a["frame"], frame);
    EXPECT_EQ(b["frame"], frame);
    const auto seq = a["seq"].get<std::uint64_t>();
    left.say("ready " + std::to_string(seq));
    right.say("ready " + std::to_string(seq));
    return seq;
  };
  // Frame 0: both ready, both told to show it; both are in the barrier now.
  sendFrame(*r, 0, 0x10);
  auto seq = readyBoth(0);
  ASSERT_TRUE(left.shown(seq) && right.shown(seq));
  // Frame 1: the right page goes silent. The left one is shown frame 1 once the timeout passed,
  // and the sink names the page that left.
  sendFrame(*r, 1, 0x20);
  const auto one = left.frame();
  ASSERT_FALSE(one.is_null());
  const auto seq1 = one["seq"].get<std::uint64_t>();
  const auto silent = right.frame();  // it has frame 1, and says nothing
  ASSERT_EQ(silent["seq"], seq1);
  left.say("ready " + std::to_string(seq1));
  ASSERT_TRUE(left.shown(seq1));
  EXPECT_NE(sink.log().find("display page r0c1"), std::string::npos);
  EXPECT_NE(sink.log().find("left the swap barrier: not ready within 300 ms"), std::string::npos)
      << sink.log();
  // Frame 2: the left page switches without waiting for anyone (the right one still holds frame
  // 1 in flight, so it is not sent frame 2).
  sendFrame(*r, 2, 0x30);
  const auto two = left.frame();
  ASSERT_EQ(two["frame"], 2);
  left.say("ready " + std::to_string(two["seq"].get<std::uint64_t>()));
  ASSERT_TRUE(left.shown(two["seq"].get<std::uint64_t>()));
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.displayPagesInBarrier == 1; }));
  // The right page catches up: it is shown frame 1 alone and gets frame 2; ready for frame 3 in
  // time, it is in the barrier again and switches with the left one.
  right.say("ready " + std::to_string(seq1));
  ASSERT_TRUE(right.shown(seq1));
  const auto caughtUp = right.frame();
  ASSERT_EQ(caughtUp["frame"], 2);
  right.say("ready " + caughtUp["seq"].dump());
  ASSERT_TRUE(right.shown(caughtUp["seq"].get<std::uint64_t>()));
  sendFrame(*r, 3, 0x40);
  const auto a = left.frame(), b = right.frame();
  ASSERT_EQ(a["frame"], 3);
  ASSERT_EQ(b["frame"], 3);
  seq = a["seq"].get<std::uint64_t>();
  // The right page first (the round waits only for the left one, so it must be in before that).
  right.say("ready " + std::to_string(seq));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.displayPagesInBarrier == 2; }))
      << sink.log();
  left.say("ready " + std::to_string(seq));
  EXPECT_TRUE(left.shown(seq));
  EXPECT_TRUE(right.shown(seq));
  EXPECT_NE(sink.log().find("is in the swap barrier"), std::string::npos) << sink.log();
}

TEST(DisplayPages, ATokenGuardsThePagesToo) {
  test::SinkRunner sink(webSink("s3cret"));
  Page page(sink.sink().httpPort(), "r0c0");
  ASSERT_TRUE(page.open());
  // Nothing about the wall before the token: only that one is needed.
  EXPECT_EQ(page.info(), nlohmann::json::parse(R"({"type":"login"})"));
  auto r = rank(sink.port(), "s3cret");
  sendFrame(*r, 0, 0x10);
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 1; }));
  EXPECT_EQ(sink.sink().stats().displayPages, 0);  // not in the barrier before "auth"
  page.say("auth s3cret");
  const auto meta = page.frame();  // the newest frame comes once it is authenticated
  ASSERT_FALSE(meta.is_null());
  EXPECT_EQ(meta["frame"], 0);
  ASSERT_EQ(page.notes().size(), 2u);  // then the display, before the frame
  EXPECT_EQ(page.notes()[0]["type"], "auth");
  EXPECT_EQ(page.notes()[1]["type"], "display");
  EXPECT_EQ(page.notes()[1]["name"], "r0c0");
  Page wrong(sink.sink().httpPort(), "r0c1");
  wrong.say("auth guess");
  EXPECT_TRUE(wrong.frame().is_null());  // closed
}

// 16 pages of one display from one address held every page's place (12 on this two-display
// wall), and the wall's own pages were refused (503). Now a page of a display with fewer pages
// takes the place of the most crowded display's oldest, and a page from another address takes
// the crowding address's oldest: both of the wall's pages come in and show the frame.
TEST(DisplayPages, PagesCrowdingADisplayLeaveRoomForEveryDisplaysPage) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  std::vector<std::unique_ptr<Page>> crowd;
  int crowdIn = 0;
  for (int i = 0; i < 16; ++i) {
    crowd.push_back(std::make_unique<Page>(port, "r0c0", "127.0.0.2"));
    crowdIn += crowd.back()->open();
  }
  EXPECT_EQ(crowdIn, 12);  // the rest found no place: one address, one display
  Page right(port, "r0c1");
  ASSERT_TRUE(right.open()) << sink.log();
  Page left(port, "r0c0");
  ASSERT_TRUE(left.open()) << sink.log();
  // A page of the crowding address for the display it crowds is still refused.
  EXPECT_FALSE(Page(port, "r0c0", "127.0.0.2").open());
  EXPECT_NE(sink.log().find("held the most"), std::string::npos) << sink.log();
  auto r = rank(sink.port());
  sendFrame(*r, 0, 0x0000ff);
  for (Page* page : {&left, &right}) {
    const auto f = page->frame();
    ASSERT_FALSE(f.is_null());
    EXPECT_EQ(f["frame"], 0);
  }
}
