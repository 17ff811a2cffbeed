// The sink's browser view (`voxwall sink --http`) against clients on loopback: the page, what is
// refused (token, Origin, garbage, oversized messages, paths), viewers that never read, many
// viewers at once, and interactive (reduced) frames arriving upsampled and whole. The real
// browser test is tests/web/wall_page_test.py.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/time.h>

#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>
#include <utility>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/frame_pixels.hpp>
#include <voxwall/walls/web_view.hpp>

#include "support/sink_runner.hpp"
#include "support/web_clients.hpp"

using namespace voxwall;
using namespace voxwall::test;

// One 800x500 display: frames of noise far larger than the loopback socket buffers take unread.
static walls::Wall bigWall() {
  return walls::parseWall(R"({"wall": "big", "display": {"width": 800, "height": 500},
                              "grid": {"columns": 1, "rows": 1}})",
                          "test");
}

TEST(WebView, ServesThePageAndNothingElse) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  ASSERT_NE(port, 0);
  const auto [status, body] = get(port, "/");
  EXPECT_EQ(status, 200);
  EXPECT_NE(body.find("<canvas"), std::string::npos);
  EXPECT_EQ(body, walls::webPage());
  EXPECT_EQ(get(port, "/index.html").first, 200);
  // No request maps to a file: not the sources, not /etc/passwd.
  for (const char* path : {"/../etc/passwd", "/%2e%2e/etc/passwd", "/web/index.html", "/etc/passwd",
                           "//etc/passwd", "/ws"})
    EXPECT_EQ(get(port, path).first, 404) << path;
  EXPECT_EQ(get(port, "/", http::verb::post).first, 405);
  EXPECT_EQ(get(port, "/", http::verb::delete_).first, 405);
  // Headers over 8 KiB: refused before they are held.
  EXPECT_NE(get(port, "/", http::verb::get, 20000).first, 200);
  // DNS rebinding: another site's name pointed at 127.0.0.1 is not served; loopback names, on
  // any port (an SSH tunnel's), are.
  EXPECT_EQ(get(port, "/", http::verb::get, 0, "evil.example:" + std::to_string(port)).first, 403);
  EXPECT_EQ(get(port, "/ws", http::verb::get, 0, "evil.example").first, 403);
  EXPECT_EQ(get(port, "/", http::verb::get, 0, "localhost:9000").first, 200);
  EXPECT_EQ(get(port, "/", http::verb::get, 0, "[::1]:9000").first, 200);
  // The server is still there.
  EXPECT_EQ(get(port, "/").first, 200);
}

// The status line's code of a raw request (0 when the server closed without answering).
static int rawStatus(std::uint16_t port, const std::string& request) {
  boost::asio::io_context io;
  tcp::socket s(io);
  s.connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
  boost::system::error_code ec;
  boost::asio::write(s, boost::asio::buffer(request), ec);
  std::string got;
  char buf[256];
  while (got.find("\r\n") == std::string::npos) {
    const auto n = s.read_some(boost::asio::buffer(buf), ec);
    if (ec) break;
    got.append(buf, n);
  }
  return got.starts_with("HTTP/1.1 ") && got.size() >= 12 ? std::stoi(got.substr(9, 3)) : 0;
}

// The Host check took "[::1]evil.example" and "127.0.0.1:evil" as loopback and the first of two
// Host headers; oversized requests were closed without a status.
TEST(WebView, HostIsOneAuthorityAndOversizedRequestsGetTheirStatus) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  for (const char* bad : {"[::1]evil.example", "127.0.0.1:evil", "127.0.0.1:99999",
                          "127.0.0.1:80:80", "evil.example/127.0.0.1", "[::1"})
    EXPECT_EQ(get(port, "/", http::verb::get, 0, bad).first, 400) << bad;
  for (const char* good : {"localhost:8080", "LOCALHOST", "127.0.0.1", "[::1]:1"})
    EXPECT_EQ(get(port, "/", http::verb::get, 0, good).first, 200) << good;
  EXPECT_EQ(rawStatus(port, "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nHost: evil.example\r\n\r\n"),
            400);
  EXPECT_EQ(rawStatus(port, "GET / HTTP/1.1\r\n\r\n"), 400);  // no Host
  EXPECT_EQ(get(port, "/", http::verb::get, 20000).first, 431);
  EXPECT_EQ(get(port, "/" + std::string(3000, 'a')).first, 414);
  EXPECT_EQ(get(port, "/").first, 200);
}

TEST(WebView, AnotherOriginGivenOnTheCommandLineMayWatch) {
  auto settings = webSink();
  settings.httpOrigins = {"http://wallhost.lab:8080"};
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  EXPECT_EQ(get(port, "/", http::verb::get, 0, "wallhost.lab:8080").first, 200);
  EXPECT_EQ(get(port, "/", http::verb::get, 0, "wallhost.lab:9999").first, 403);
}

TEST(WebView, RefusesAForeignOriginAndTakesItsOwn) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  Viewer evil(port, "http://evil.example");
  EXPECT_FALSE(evil.open());
  Viewer own(port, "http://127.0.0.1:" + std::to_string(port));
  ASSERT_TRUE(own.open()) << own.error().message();
  const auto wall = nlohmann::json::parse(own.read());
  EXPECT_EQ(wall["type"], "wall");
  EXPECT_EQ(wall["width"], 44);
  EXPECT_EQ(wall["displays"].size(), 2u);
  EXPECT_FALSE(wall["token"].get<bool>());
  EXPECT_NE(sink.log().find("refused a viewer from Origin \"http://evil.example\""),
            std::string::npos)
      << sink.log();
}

TEST(WebView, ATokenGuardsFramesAndControl) {
  test::SinkRunner sink(webSink("s3cret"));
  const auto port = sink.sink().httpPort();
  // Rank 0's control connection, to see what reaches it.
  net::ControlChannel control("127.0.0.1", sink.port(),
                              net::Hello{net::Role::Controller, 0, 1, "t2x1", "s3cret"});
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }));
  {
    Viewer v(port);
    ASSERT_TRUE(v.open());
    // Nothing about the wall before the token: only that one is needed.
    EXPECT_EQ(nlohmann::json::parse(v.read()), nlohmann::json::parse(R"({"type":"login"})"));
    v.send("rotate 10 0");
    EXPECT_TRUE(v.closedByServer());
    EXPECT_EQ(v.closeReason(), "a command before the token");
  }
  {
    Viewer v(port);
    v.read();
    v.send("auth wrong");
    EXPECT_TRUE(v.closedByServer());
    EXPECT_EQ(v.closeReason(), "wrong token");
  }
  // Nothing of the refused viewers reached rank 0: the one command that arrives below is the
  // authenticated viewer's (they were closed before it connected). The right token is taken
  // once the back-off after the wrong one has passed (0.1 s).
  std::unique_ptr<Viewer> authed;
  ASSERT_TRUE(test::waitUntil([&] {
    authed = std::make_unique<Viewer>(port);
    authed->read();
    authed->send("auth s3cret");
    return authed->read().find("\"auth\"") != std::string::npos;
  }));
  Viewer& v = *authed;
  const auto wall = nlohmann::json::parse(v.read());  // the wall, now
  EXPECT_EQ(wall["type"], "wall");
  EXPECT_EQ(wall["width"], 44);
  v.send("rotate 10 -5");
  std::vector<net::Control> got;
  test::waitUntil([&] {
    got = control.drain();
    return !got.empty();
  });
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].command, net::ControlCommand::Rotate);
  EXPECT_DOUBLE_EQ(got[0].a, 10);
  EXPECT_DOUBLE_EQ(got[0].b, -5);
}

// With a token, connections that never send it held viewers' places for ever and locked out
// the token's holder. They now wait in a pool of their own (4 per address) for at most the
// auth deadline.
TEST(WebView, ConnectionsWithoutTheTokenWaitApartAndBriefly) {
  auto settings = webSink("s3cret");
  settings.maxViewers = 2;
  settings.viewerAuthTimeoutMs = 300;
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  std::vector<std::unique_ptr<Viewer>> squatters;
  for (int i = 0; i < 4; ++i) {
    squatters.push_back(std::make_unique<Viewer>(port, "", "/ws", "127.0.0.2"));
    ASSERT_TRUE(squatters.back()->open()) << squatters.back()->error().message();
  }
  Viewer fifth(port, "", "/ws", "127.0.0.2");
  EXPECT_FALSE(fifth.open());
  EXPECT_TRUE(sink.waitForLog("4 from 127.0.0.2 are waiting for their token")) << sink.log();
  // The holder of the token gets in from another address, though 4 are waiting and only 2
  // viewers are allowed.
  Viewer holder(port);
  ASSERT_TRUE(holder.open()) << holder.error().message();
  holder.read();
  holder.send("auth s3cret");
  EXPECT_EQ(nlohmann::json::parse(holder.read())["type"], "auth");
  for (auto& v : squatters) {
    EXPECT_TRUE(v->closedByServer());
    EXPECT_EQ(v->closeReason(), "no token within 300 ms");
  }
  // Their places are free again.
  Viewer later(port, "", "/ws", "127.0.0.2");
  EXPECT_TRUE(later.open()) << later.error().message();
}

// A viewer that reads nothing but sends pings kept its place: any byte it sent reset its idle
// timer. It is now judged by what it reads: a frame not taken within the write deadline cuts it
// off.
TEST(WebView, AViewerThatSendsButNeverReadsIsCutOff) {
  auto settings = webSink();
  settings.wall = bigWall();
  settings.viewerWriteTimeoutMs = 300;
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  Viewer stuck(port);
  ASSERT_TRUE(stuck.open());
  Renderer rank(sink.port(), "big", 800, 500);
  std::uint64_t f = 0;
  // Frames of noise until its socket buffers are full and a write waits past the deadline; it
  // pings all along.
  ASSERT_TRUE(test::waitUntil([&] {
    rank.frame(f++, 1, true);
    stuck.ping();
    return sink.log().find("(read nothing for 300 ms)") != std::string::npos;
  })) << sink.log();
  // Tile intake never waited for it: every frame was presented.
  EXPECT_TRUE(sink.waitFor([&](const walls::SinkStats& st) {
    return st.framesPresented == int(f);
  })) << sink.log();
  Viewer next(port);
  EXPECT_TRUE(next.open());
}

// Guessing the page's token gained nothing from being slow, and cost a log line each. The tile
// port's back-off per address now guards the WebSockets too, and the log counts the guesses.
TEST(WebView, WrongTokensBackOffPerAddressAndAreCountedNotLoggedEach) {
  test::SinkRunner sink(webSink("s3cret"));
  const auto port = sink.sink().httpPort();
  int heard = 0, guesses = 0;  // wrong tokens the sink listened to; the others were refused unheard
  auto guess = [&] {
    Viewer v(port);
    EXPECT_TRUE(v.open());
    v.read();
    v.send("auth guess" + std::to_string(guesses++));
    EXPECT_TRUE(v.closedByServer());
    const std::string why = v.closeReason();
    EXPECT_NE(why.find("wrong token"), std::string::npos) << why;
    if (why.find("too many wrong tokens") == std::string::npos) ++heard;
  };
  for (int i = 0; i < 40; ++i) guess();
  // The back-off doubles with each wrong token heard: after six it is 3.2 s, so the right token
  // that follows at once is refused unheard however slow the machine (after one it is 0.1 s,
  // which 40 quick guesses can use up).
  EXPECT_TRUE(test::waitUntil([&] { return guess(), heard >= 6; }, std::chrono::seconds(60)));
  const std::string log = sink.log();
  int lines = 0;
  for (auto at = log.find("wrong token ("); at != std::string::npos;
       at = log.find("wrong token (", at + 1))
    ++lines;
  EXPECT_GE(lines, 1) << log;
  EXPECT_LE(lines, 4) << log;
  EXPECT_EQ(log.find("closed: wrong token"), std::string::npos) << log;
  {
    Viewer early(port);
    early.read();
    early.send("auth s3cret");
    EXPECT_TRUE(early.closedByServer());
    EXPECT_NE(early.closeReason().find("too many wrong tokens from 127.0.0.1"), std::string::npos)
        << early.closeReason();
  }
  EXPECT_TRUE(test::waitUntil([&] {
    Viewer later(port);
    later.read();
    later.send("auth s3cret");
    return later.read().find("\"auth\"") != std::string::npos;
  })) << sink.log();
}

// Reconnecting after every burst of commands got a new budget each time (2,300 commands a
// second). The budget is now the address's.
TEST(WebView, ReconnectingDoesNotRefillTheCommandBudget) {
  test::SinkRunner sink(webSink());
  net::ControlChannel control("127.0.0.1", sink.port(),
                              net::Hello{net::Role::Controller, 0, 1, "t2x1", ""});
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }));
  const auto port = sink.sink().httpPort();
  {
    Viewer first(port);
    first.read();
    for (int i = 0; i < 100; ++i) first.send("rotate 1 0");  // within the burst of 120
  }
  Viewer second(port);
  second.read();
  for (int i = 0; i < 100; ++i) second.send("rotate 1 0");
  bool told = false;
  for (int i = 0; i < 100 && !told; ++i) {
    const auto m = second.read();
    ASSERT_FALSE(second.error()) << second.error().message();
    told = m.find("too many commands") != std::string::npos;
  }
  EXPECT_TRUE(told);
}

// A viewer that floods commands: a burst of 120 goes through, the rest are dropped and it is told.
TEST(WebView, CommandsBeyondTheRateAreDroppedAndTheViewerIsTold) {
  test::SinkRunner sink(webSink());
  net::ControlChannel control("127.0.0.1", sink.port(),
                              net::Hello{net::Role::Controller, 0, 1, "t2x1", ""});
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }));
  Viewer v(sink.sink().httpPort());
  v.read();
  constexpr int kSent = 400;  // refilling 280 commands at 60/s would take over 4 s
  for (int i = 0; i < kSent; ++i) v.send("rotate 1 0");
  bool told = false;
  for (int i = 0; i < 50 && !told; ++i) {
    const auto m = v.read();
    ASSERT_FALSE(v.error()) << v.error().message();
    told = m.find("too many commands") != std::string::npos;
  }
  EXPECT_TRUE(told);
  // The burst arrives (within 10 s: a deadline, not a timing assertion); the rest was dropped.
  std::size_t got = 0;
  test::waitUntil([&] {
    got += control.drain().size();
    return got >= 120;
  });
  got += control.drain().size();
  EXPECT_GE(got, 120u);
  EXPECT_LT(got, std::size_t(kSent));
}

// Connections that never send a request hold at most 256 places, each for at most 10 s.
TEST(WebView, IdleConnectionsAreBoundedAndCutOff) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  boost::asio::io_context io;
  std::vector<std::unique_ptr<tcp::socket>> idle;
  for (int i = 0; i < 256; ++i) {
    idle.push_back(std::make_unique<tcp::socket>(io));
    idle.back()->connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
  }
  // Once the server has taken all 256, a request is closed unanswered: no place left. (Waits
  // for it with a deadline: until then a request may still find a place.)
  auto eventually = [&](int status) {
    return test::waitUntil([&] { return get(port, "/").first == status; });
  };
  EXPECT_TRUE(eventually(0));
  idle.clear();
  EXPECT_TRUE(eventually(200));  // the places come back as the idle connections close
}

// 260 connections trickling header bytes held every request's place (7 of 41 page requests
// were answered, and nothing was logged). One address now holds at most 16 places.
TEST(WebView, SlowRequestsFromOneAddressLeaveRoomForOthers) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  boost::asio::io_context io;
  std::vector<std::unique_ptr<tcp::socket>> slow;
  for (int i = 0; i < 300; ++i) {
    auto s = std::make_unique<tcp::socket>(io);
    s->open(tcp::v4());
    s->bind(tcp::endpoint(boost::asio::ip::make_address("127.0.0.2"), 0));
    s->connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
    boost::system::error_code ignored;
    boost::asio::write(*s, boost::asio::buffer(std::string("GET / HTTP/1.1\r\nHo")), ignored);
    slow.push_back(std::move(s));
  }
  EXPECT_TRUE(sink.waitForLog("requests in flight from 127.0.0.2")) << sink.log();
  // Others are still served, every time.
  for (int i = 0; i < 20; ++i) EXPECT_EQ(get(port, "/").first, 200) << i;
  Viewer viewer(port);
  EXPECT_TRUE(viewer.open()) << viewer.error().message();
}

// 256 requests in flight from 16 addresses (16 each, the most one address may have) left
// nothing for anyone else: a request from another address was closed unanswered. Now it comes
// in, in place of the oldest request of an address holding the most.
TEST(WebView, RequestsFromManyAddressesLeaveRoomForAnother) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  boost::asio::io_context io;
  std::vector<std::unique_ptr<tcp::socket>> slow;
  for (int a = 0; a < 16; ++a)
    for (int i = 0; i < 16; ++i) {
      auto s = std::make_unique<tcp::socket>(io);
      s->open(tcp::v4());
      s->bind(tcp::endpoint(boost::asio::ip::make_address("127.0.1." + std::to_string(a + 2)), 0));
      s->connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
      boost::system::error_code ignored;
      boost::asio::write(*s, boost::asio::buffer(std::string("GET / HTTP/1.1\r\nHo")), ignored);
      slow.push_back(std::move(s));
    }
  for (int i = 0; i < 5; ++i) EXPECT_EQ(get(port, "/").first, 200) << i << sink.log();
  EXPECT_TRUE(sink.waitForLog("its address had the most")) << sink.log();
}

// With a token, 14 WebSockets waiting for theirs from 4 addresses filled the waiting pool
// (--max-viewers 2 plus 12 pages) and the token's holder got 503 while they reconnected. Now the
// holder comes in, in place of the oldest of an address waiting most, and is let in.
TEST(WebView, AWaitingPoolFullOfTheUnprovenLetsTheTokensHolderIn) {
  auto settings = webSink("s3cret");
  settings.maxViewers = 2;
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  std::vector<std::unique_ptr<Viewer>> waiting;
  for (int i = 0; i < 14; ++i) {
    waiting.push_back(
        std::make_unique<Viewer>(port, "", "/ws", "127.0.2." + std::to_string(2 + i / 4)));
    ASSERT_TRUE(waiting.back()->open()) << i << " " << waiting.back()->error().message();
    waiting.back()->read();  // {"type":"login"}: it is in the pool
  }
  Viewer holder(port);
  ASSERT_TRUE(holder.open()) << holder.error().message() << sink.log();
  holder.read();
  holder.send("auth s3cret");
  EXPECT_EQ(nlohmann::json::parse(holder.read())["type"], "auth");
  EXPECT_TRUE(waiting.front()->closedByServer());
  EXPECT_EQ(waiting.front()->closeReason(), "replaced: too many waiting for their token");
}

TEST(WebView, GarbageAndOversizedMessagesCloseTheViewerNotTheSink) {
  test::SinkRunner sink(webSink());
  const auto port = sink.sink().httpPort();
  // The reason the page is told, where the server gives one (Beast itself closes on a message
  // over the limit and on text that is not UTF-8).
  const std::pair<std::string, std::string> cases[] = {
      {"binary", "binary messages are not taken"},
      {"oversized", ""},
      {"fly to the moon", "\"fly to the moon\": commands"},
      {"zoom -1", "\"zoom -1\": zoom takes a factor from 0.001 to 1000"},
      {"rotate 1e308 1e308", "\"1e308\" is not a number within +-1e6"},
      {"zoom 2abc", "\"2abc\" is not a number"},
      {"rotate 1 2 3", "rotate takes 2 numbers"},
      {std::string("rotate \0\xff 1", 11), ""},
      {"auth", "commands"},
  };
  for (const auto& [what, reason] : cases) {
    Viewer v(port);
    ASSERT_TRUE(v.open());
    v.read();
    if (what == "binary")
      v.sendBinary(std::string("\x00\x01\x02", 3));
    else if (what == "oversized")
      v.send(std::string(5000, 'x'));
    else
      v.send(what);
    EXPECT_TRUE(v.closedByServer()) << what << ": " << v.error().message();
    if (!reason.empty()) {
      EXPECT_NE(v.closeReason().find(reason), std::string::npos) << what << ": " << v.closeReason();
    }
  }
  // Raw garbage where an HTTP request belongs.
  {
    boost::asio::io_context io;
    tcp::socket s(io);
    s.connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
    boost::asio::write(s, boost::asio::buffer(std::string("\x16\x03\x01garbage\r\n\r\n")));
    char buf[64];
    beast::error_code ec;
    while (!ec) s.read_some(boost::asio::buffer(buf), ec);  // the server closes
  }
  Viewer still(port);
  EXPECT_TRUE(still.open());
}

// Tiles first: a viewer that never reads does not slow the wall; the others get the newest frame.
// The frames are noise, 800x500: far more than the loopback socket buffers can take unread.
TEST(WebView, AViewerThatNeverReadsDoesNotStallTileIntake) {
  auto settings = webSink();
  settings.wall = bigWall();
  // The reader below starts reading only once all frames were presented (slow under ASan): the
  // viewers' deadline (10 s) is not what this test is about.
  settings.viewerWriteTimeoutMs = 600000;
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  Viewer stuck(port);  // connects, then never reads a byte
  ASSERT_TRUE(stuck.open());
  Viewer reader(port);
  ASSERT_TRUE(reader.open());
  ASSERT_TRUE(nlohmann::json::parse(reader.read())["type"] == "wall");
  Renderer rank(sink.port(), "big", 800, 500);
  constexpr int kFrames = 120;
  for (int f = 0; f < kFrames; ++f) rank.frame(std::uint64_t(f), 1, true);
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == kFrames; }))
      << sink.log();
  EXPECT_EQ(sink.sink().stats().framesDropped, 0);
  // The reader gets frames, the newest among them, while the stuck one is still connected.
  std::uint64_t last = 0;
  for (int i = 0; i < kFrames; ++i) {
    const auto meta = reader.readFrame();
    ASSERT_FALSE(meta.is_null()) << reader.error().message();
    last = meta["frame"].get<std::uint64_t>();
    if (last == kFrames - 1) break;
  }
  EXPECT_EQ(last, std::uint64_t(kFrames - 1));
  EXPECT_EQ(sink.sink().stats().framesPresented, kFrames);
}

// A viewer reading 10 messages a second was still on frame 586 a minute after the render ended:
// "newest wins" began only once the socket buffers were full. A viewer now has one frame in
// flight: the next it gets, once it said "next", is the newest.
TEST(WebView, ASlowViewersNextFrameIsTheNewest) {
  test::SinkRunner sink(webSink());
  Viewer v(sink.sink().httpPort()), watcher(sink.sink().httpPort());
  ASSERT_TRUE(v.open() && watcher.open());
  v.read(), watcher.read();  // the wall: both are registered for frames now
  Renderer rank(sink.port());
  rank.frame(0);
  const auto first = v.readFrame(nullptr, false);  // taken, but no "next" yet
  ASSERT_FALSE(first.is_null()) << v.error().message();
  EXPECT_EQ(first["frame"], 0);
  for (std::uint64_t f = 1; f <= 20; ++f) rank.frame(f);
  // The overview pictures are made on a thread of their own, the newest first: once a viewer
  // that keeps reading got frame 20's, that is what waits for the slow one.
  std::uint64_t seen = 0;
  for (int i = 0; i < 21 && seen != 20; ++i) {
    const auto meta = watcher.readFrame();
    ASSERT_FALSE(meta.is_null()) << watcher.error().message();
    seen = meta["frame"].get<std::uint64_t>();
  }
  ASSERT_EQ(seen, 20u);
  v.send("next");
  const auto next = v.readFrame();
  ASSERT_FALSE(next.is_null()) << v.error().message();
  EXPECT_EQ(next["frame"], 20) << "the frame after 0 was not the newest";
}

TEST(WebView, FiftyViewersAtOnceEachGetTheFrame) {
  auto settings = webSink();
  settings.maxViewers = 50;
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  std::vector<std::unique_ptr<Viewer>> viewers;
  for (int i = 0; i < 50; ++i) {
    viewers.push_back(std::make_unique<Viewer>(port));
    ASSERT_TRUE(viewers.back()->open()) << i;
    viewers.back()->read();
  }
  EXPECT_FALSE(Viewer(port).open());  // the 51st is refused
  Renderer rank(sink.port());
  rank.frame(0);
  for (auto& v : viewers) {
    std::string jpeg;
    const auto meta = v->readFrame(&jpeg);
    ASSERT_FALSE(meta.is_null()) << v->error().message();
    EXPECT_EQ(meta["frame"], 0);
    EXPECT_EQ(meta["width"], 44);
    // The rank's two halves share an edge whole: the overlay shows one rectangle.
    ASSERT_EQ(meta["tiles"].size(), 1u);
    EXPECT_EQ(meta["tiles"][0]["w"], 44);
    EXPECT_EQ(meta["tiles"][0]["h"], 10);
    EXPECT_EQ(meta["tiles"][0]["rank"], 0);
    EXPECT_EQ(meta["ranks"]["0"], 1.5);  // the rank's render time, in ms
    const auto image = net::decodeTile(std::as_bytes(std::span(jpeg.data(), jpeg.size())),
                                       net::TileCodec::Jpeg, 44, 10, "viewer frame");
    EXPECT_EQ(image.width, 44);
  }
}

// Viewers coming and going (10,649 log lines a second of churn beside a stream before): at most
// 8 lines of comings and goings per kind every 10 s are told (bounded by the time the test took,
// not timed), and the sink still serves.
TEST(WebView, ViewersComingAndGoingCannotFloodTheLog) {
  auto settings = webSink();
  settings.maxViewers = 64;  // 40 in a row, each closing as the next comes
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 40; ++i) {
    Viewer v(port);
    ASSERT_TRUE(v.open()) << i;
    v.read();
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::size_t windows = 1 + std::size_t(seconds / 10);
  EXPECT_EQ(get(port, "/").first, 200);
  const std::string log = sink.log();
  std::size_t lines = 0;
  for (auto at = log.find(" watching"); at != std::string::npos; at = log.find(" watching", at + 1))
    ++lines;
  EXPECT_GE(lines, 1u) << log;
  EXPECT_LE(lines, 8 * windows) << log;
}

// Viewers from one address held every viewer's place and everyone else got 503 for as long as
// they stayed. Now a viewer from another address takes the crowding address's oldest place;
// one from the crowding address is refused.
TEST(WebView, ViewersFromOneAddressLeaveRoomForOthers) {
  auto settings = webSink();
  settings.maxViewers = 8;
  test::SinkRunner sink(settings);
  const auto port = sink.sink().httpPort();
  std::vector<std::unique_ptr<Viewer>> crowd;
  for (int i = 0; i < 8; ++i) {
    crowd.push_back(std::make_unique<Viewer>(port, "", "/ws", "127.0.0.2"));
    ASSERT_TRUE(crowd.back()->open()) << i;
    crowd.back()->read();
  }
  EXPECT_FALSE(Viewer(port, "", "/ws", "127.0.0.2").open());
  Viewer mine(port);
  ASSERT_TRUE(mine.open()) << sink.log();
  mine.read();
  Renderer rank(sink.port());
  rank.frame(0);
  const auto meta = mine.readFrame();
  ASSERT_FALSE(meta.is_null()) << mine.error().message();
  EXPECT_EQ(meta["frame"], 0);
}

// An interactive frame (1/4 per side) is presented whole: every virtual-screen pixel repeats the
// reduced pixel of its block, up to the clipped blocks at the right and bottom edges.
TEST(WebView, AnInteractiveFrameArrivesUpsampledAndWhole) {
  auto settings = webSink();
  walls::AssembledFrame got;
  walls::FrameAssembler assembler(settings.wall, {}, {});
  const int step = 4, w = net::reducedSide(44, step), h = net::reducedSide(10, step);
  ASSERT_EQ(w, 11);
  ASSERT_EQ(h, 3);
  voxwall::Image reduced(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) reduced.at(x, y) = 0xff000000u | std::uint32_t(x * 20 + y);
  net::TileCodecSettings s;
  s.codec = net::TileCodec::Raw;
  const auto left = net::encodeTiles(reduced.crop({0, 0, 5, h}), {0, 0, 5, h}, {0, 0, 0}, s)[0];
  const auto right =
      net::encodeTiles(reduced.crop({5, 0, w - 5, h}), {5, 0, w - 5, h}, {0, 0, 0}, s)[0];
  EXPECT_FALSE(assembler.addTile(3, net::TileMessage{left.rect, left.codec, 0, left.bytes, step, 0},
                                 0, "rank 0"));
  // A tile of the same frame at another step is refused; nothing of it is marked.
  EXPECT_THROW(assembler.addTile(3, net::TileMessage{right.rect, right.codec, 0, right.bytes, 2, 0},
                                 1, "rank 1"),
               FormatError);
  // A rectangle off the reduced screen is refused.
  EXPECT_THROW(
      assembler.addTile(3, net::TileMessage{{5, 0, w - 4, h}, right.codec, 0, right.bytes, step, 0},
                        1, "rank 1"),
      FormatError);
  const auto done = assembler.addTile(
      3, net::TileMessage{right.rect, right.codec, 0, right.bytes, step, 0}, 1, "rank 1");
  ASSERT_TRUE(done);
  EXPECT_EQ(done->step, step);
  const auto image = walls::decodeRegion(*done, {0, 0, 44, 10}, 1, 0);
  ASSERT_EQ(image.width, 44);
  ASSERT_EQ(image.height, 10);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 44; ++x)
      ASSERT_EQ(image.at(x, y), reduced.at(x / step, y / step)) << x << "," << y;
  ASSERT_EQ(done->segments.size(), 2u);
  EXPECT_EQ(done->segments[1].screen, (voxwall::Rect{20, 0, 24, 10}));  // clipped at the edges
  EXPECT_EQ(done->segments[1].rank, 1);
}

TEST(WebView, ViewersSeeTheStepOfAnInteractiveFrame) {
  test::SinkRunner sink(webSink());
  Viewer v(sink.sink().httpPort());
  v.read();
  Renderer rank(sink.port());
  rank.frame(0, 4);
  const auto meta = v.readFrame();
  ASSERT_FALSE(meta.is_null());
  EXPECT_EQ(meta["step"], 4);
  EXPECT_NE(sink.log().find("frame 0 presented"), std::string::npos);
  EXPECT_NE(sink.log().find("interactive 1/4"), std::string::npos) << sink.log();
}
