// Regression tests for hostile or confused peers: each case crashed, wedged, stalled or bloated
// the sink before it was hardened (see docs/wall.md, "What a peer cannot do").
#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>
#include <xxhash.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/frame_files.hpp>
#include <voxwall/walls/log_throttle.hpp>
#include <voxwall/walls/sink.hpp>
#include <voxwall/walls/sink_core.hpp>

#include "support/sink_runner.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;

namespace {

net::Hello rendererHello(int rank, int ranks, std::uint64_t job = 0) {
  net::Hello h{net::Role::Renderer, rank, ranks, "t2x1", ""};
  h.jobId = job;
  return h;
}

net::TileMessage solidTileMessage(const voxwall::Rect& rect, std::uint32_t rgb) {
  voxwall::Image image(rect.width, rect.height);
  for (auto& p : image.pixels) p = rgb | 0xff000000u;
  net::TileCodecSettings s;
  s.codec = net::TileCodec::Raw;
  const auto t = net::encodeTiles(image, rect, {0, 0, 0}, s)[0];
  return {t.rect, t.codec, 0, t.bytes};
}

const net::TileMessage& wholeScreen() {
  static const auto tile = solidTileMessage({0, 0, 44, 10}, 0x808080);
  return tile;
}

// A TCP connection to the sink, from `from` (another loopback address: 127.0.0.2) if given.
int rawConnect(std::uint16_t port, const char* from = nullptr) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd >= 0 && from) {
    sockaddr_in local{};
    local.sin_family = AF_INET;
    ::inet_pton(AF_INET, from, &local.sin_addr);
    if (::bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
      ::close(fd);
      return -1;
    }
  }
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// Whether the sink closed the connection within `ms` (a deadline, not a timing assertion: what
// closes the connection is told apart by the sink's log).
bool closedWithin(int fd, int ms) {
  for (int waited = 0; waited < ms; waited += 10) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 10) > 0) {
      std::byte buf[4096];
      if (::recv(fd, buf, sizeof buf, 0) <= 0) return true;
    }
  }
  return false;
}

// The reason of the Bye the sink sent on `c` (within 5 s; empty when none came).
std::string byeOf(net::Connection& c) {
  try {
    for (int i = 0; i < 500; ++i)
      if (const auto m = c.receive(10); m && m->type == net::MessageType::Bye)
        return net::decodeBye(m->payload, "sink").reason;
  } catch (const net::NetError&) {
    // closed (after its Bye, which was read above, or without one)
  }
  return "";
}

}  // namespace

// x + width overflowed a signed int and the sink wrote far outside its frame.
TEST(SinkHardening, TileRectangleThatOverflowsDropsThePeerNotTheSink) {
  test::SinkRunner sink(test::twoDisplaySink());
  auto c = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 2000);
  for (const voxwall::Rect r :
       {voxwall::Rect{2147483647 - 50, 0, 100, 10}, voxwall::Rect{0, 2147483647 - 5, 44, 10}}) {
    auto tile = solidTileMessage({0, 0, r.width, r.height}, 0xff);
    tile.rect = r;
    c->send(net::encodeMessage(1, tile));
  }
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.peersDropped >= 1; }))
      << sink.log();
  EXPECT_NE(sink.log().find("is not on the 44x10 screen"), std::string::npos) << sink.log();
  auto good = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 2000);
  good->send(net::encodeMessage(2, wholeScreen()));
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 1; }))
      << sink.log();
}

// a second job's first frames were silently discarded as "old".
TEST(SinkHardening, OneJobAtATimeAndANewJobStartsANewFrameSequence) {
  test::SinkRunner sink(test::twoDisplaySink());
  auto first = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1, 111), 2000);
  for (int f : {5, 6}) {
    first->send(net::encodeMessage(std::uint64_t(f), wholeScreen()));
    ASSERT_TRUE(
        sink.waitFor([f](const walls::SinkStats& s) { return s.framesPresented == f - 4; }));
  }
  // While job 111 is connected, another job is refused, with the reason.
  try {
    net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1, 222), 2000);
    FAIL() << "a second job was let in while the first was running";
  } catch (const net::SinkRefused& e) {
    EXPECT_NE(std::string(e.what()).find("is showing on this wall"), std::string::npos) << e.what();
    // The running job's id is never told: whoever says it joins that job.
    EXPECT_EQ(std::string(e.what()).find("000000000000006f"), std::string::npos) << e.what();
  }
  EXPECT_NE(sink.log().find("job 000000000000006f is showing"), std::string::npos) << sink.log();
  first->send(net::encodeMessage(net::Bye{"done"}));
  first.reset();
  std::unique_ptr<net::Connection> second;
  test::waitUntil([&] {
    try {
      second = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1, 222), 2000);
    } catch (const net::SinkRefused&) {
      // the Bye is still in flight
    }
    return second != nullptr;
  });
  ASSERT_TRUE(second);
  // Frame 0 of the new job is shown although frame 6 of the old one was.
  second->send(net::encodeMessage(0, wholeScreen()));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 3; }))
      << sink.log();
  EXPECT_NE(sink.log().find("job 000000000000006f ended; job 00000000000000de took the wall"),
            std::string::npos)
      << sink.log();
  // The old job cannot take the wall back, even once the new one has left.
  second.reset();
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.renderersConnected == 0; }));
  try {
    net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1, 111), 2000);
    FAIL() << "the ended job took the wall back";
  } catch (const net::SinkRefused& e) {
    EXPECT_NE(std::string(e.what()).find("has ended"), std::string::npos) << e.what();
  }
}

// Whoever said a running job's id joined it: a second controller beside rank 0's, a rank twice,
// a rank past the job's count. Now a place of the job (its controller, a rank) is held by one
// connection: a new one for it is that place reconnecting and replaces the old (which hears why);
// a rank count other than the job's is refused.
TEST(SinkHardening, AJobHasOneControllerEachRankOnceAndOneRankCount) {
  test::SinkRunner sink(test::twoDisplaySink());
  auto rank0 = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 2, 333), 2000);
  net::Hello control{net::Role::Controller, 0, 2, "t2x1", ""};
  control.jobId = 333;
  auto controller = net::Connection::open("127.0.0.1", sink.port(), control, 2000);
  try {
    net::Connection::open("127.0.0.1", sink.port(), rendererHello(2, 3, 333), 2000);
    ADD_FAILURE() << "a rank of a job of 3 joined a job of 2";
  } catch (const net::SinkRefused& e) {
    EXPECT_NE(std::string(e.what()).find("says the job has 3 ranks where"), std::string::npos)
        << e.what();
  }
  auto again = net::Connection::open("127.0.0.1", sink.port(), control, 2000);
  auto rank0again = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 2, 333), 2000);
  for (auto* old : {controller.get(), rank0.get()})
    EXPECT_EQ(byeOf(*old), "replaced by a new connection of the same place");
  auto rank1 = net::Connection::open("127.0.0.1", sink.port(), rendererHello(1, 2, 333), 2000);
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) {
    return s.renderersConnected == 2 && s.controllerConnected;
  })) << sink.log();
  EXPECT_NE(sink.log().find("(controller) replaced by"), std::string::npos) << sink.log();
  EXPECT_NE(sink.log().find("(rank 0) replaced by"), std::string::npos) << sink.log();
}

// A squatter (a Hello with a job id of its own, then only keep-alives) held the wall for ever:
// every render was refused. A job that presents no frame for --job-idle gives the wall up to the
// next job that asks; its peers hear why.
TEST(SinkHardening, AJobThatPresentsNothingGivesTheWallUpAfterTheJobIdleTime) {
  auto s = test::twoDisplaySink();
  s.jobIdleMs = 300;
  test::SinkRunner sink(s);
  auto squatter = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 4, 501), 2000);
  std::unique_ptr<net::Connection> next;
  test::waitUntil([&] {
    squatter->send(net::encodeKeepAlive());
    try {
      next = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1, 502), 2000);
    } catch (const net::SinkRefused&) {
      // the squatter's job is younger than --job-idle
    }
    return next != nullptr;
  });
  ASSERT_TRUE(next) << sink.log();
  EXPECT_NE(sink.log().find("job 00000000000001f5 presented no frame for"), std::string::npos)
      << sink.log();
  EXPECT_EQ(byeOf(*squatter),
            "this job presented no frame for 0.3 s (--job-idle) and another job took the wall");
  next->send(net::encodeMessage(0, wholeScreen()));
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.framesPresented == 1; }))
      << sink.log();
}

// A peer that says Hello with its job id and then nothing held the wall for its job forever:
// every other render job was refused. A greeted peer silent for the peer-idle time is dropped,
// and once its job has no peer left another job takes the wall.
TEST(SinkHardening, ASilentPeerIsDroppedAfterTheIdleTimeAndAnotherJobTakesTheWall) {
  auto s = test::twoDisplaySink();
  s.peerIdleMs = 300;
  test::SinkRunner sink(s);
  auto squatter = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1, 111), 2000);
  std::unique_ptr<net::Connection> job;
  std::string refusal;
  ASSERT_TRUE(test::waitUntil([&] {
    try {
      job = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1, 222), 2000);
    } catch (const net::SinkRefused& e) {
      refusal = e.what();  // while the squatter is still there
    }
    return job != nullptr;
  })) << sink.log();
  EXPECT_NE(refusal.find("is showing on this wall"), std::string::npos) << refusal;
  EXPECT_EQ(refusal.find("000000000000006f"), std::string::npos) << refusal;  // 111: not told
  EXPECT_NE(sink.log().find("sent nothing for 300 ms (--peer-idle)"), std::string::npos)
      << sink.log();
  job->send(net::encodeMessage(0, wholeScreen()));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.framesPresented == 1; }))
      << sink.log();
  EXPECT_NE(sink.log().find("job 00000000000000de took the wall"), std::string::npos) << sink.log();
}

// Ranks between frames and rank 0, which sends nothing but Bye, say KeepAlive: they stay
// connected through many idle times.
TEST(SinkHardening, KeepAlivesHoldAQuietStreamerAndControllerConnected) {
  auto s = test::twoDisplaySink();
  s.peerIdleMs = 400;
  test::SinkRunner sink(s);
  net::TileStreamer streamer("127.0.0.1", sink.port(), rendererHello(0, 1, 333), 1000, 40);
  ASSERT_TRUE(streamer.beginFrame(0));
  ASSERT_TRUE(streamer.endFrame());
  auto control = rendererHello(0, 1, 333);
  control.role = net::Role::Controller;
  net::ControlChannel channel("127.0.0.1", sink.port(), control, 40);
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.controllerConnected; }));
  // 60 keep-alives of 32 bytes: about 1.2 s of both peers saying nothing else, three idle times.
  const std::uint64_t from = sink.sink().stats().bytesReceived;
  ASSERT_TRUE(sink.waitFor([&](const walls::SinkStats& st) {
    return st.bytesReceived >= from + 60 * net::kHeaderBytes;
  })) << sink.log();
  const auto now = sink.sink().stats();
  EXPECT_EQ(now.renderersConnected, 1) << sink.log();
  EXPECT_TRUE(now.controllerConnected) << sink.log();
  EXPECT_EQ(sink.log().find("sent nothing"), std::string::npos) << sink.log();
}

// one complete tile with frame id 2^64 - 1 made the sink discard every later frame.
TEST(SinkHardening, AFrameIdFarAheadIsRefusedAndReportedAndCannotWedgeTheWall) {
  test::SinkRunner sink(test::twoDisplaySink());
  net::ControlChannel control("127.0.0.1", sink.port(), rendererHello(0, 1));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }));
  auto c = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 2000);
  c->send(net::encodeMessage(1, wholeScreen()));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 1; }));
  c->send(net::encodeMessage(~std::uint64_t(0), wholeScreen()));
  c->send(net::encodeMessage(2, wholeScreen()));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) {
    return s.framesPresented == 2 && s.framesRefused == 1;
  })) << sink.log();
  EXPECT_NE(sink.log().find("frame 18446744073709551615 refused: frame id 18446744073709551615 is "
                            "more than 65536 frames ahead"),
            std::string::npos)
      << sink.log();
  // Rank 0 hears of it too.
  std::vector<std::string> notes;
  test::waitUntil([&] {
    notes = control.drainNotes();
    return !notes.empty();
  });
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes[0].find("refused"), std::string::npos) << notes[0];
  // A flood of them (77,127 log lines a second before): counted each, logged once in 10 s.
  for (std::uint64_t f = 0; f < 300; ++f)
    c->send(net::encodeMessage(~std::uint64_t(0) - f - 1, wholeScreen()));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesRefused == 301; }))
      << sink.log();
  const std::string log = sink.log();
  std::size_t lines = 0;
  for (auto at = log.find(" refused: frame id"); at != std::string::npos;
       at = log.find(" refused: frame id", at + 1))
    ++lines;
  EXPECT_LE(lines, 2u) << log;
}

// under a descriptor limit, one failed accept ended accepting for good.
TEST(SinkHardening, KeepsAcceptingAfterRunningOutOfFileDescriptors) {
  auto s = test::twoDisplaySink();
  s.helloTimeoutMs = 1500;
  test::SinkRunner sink(s);
  {  // One whole frame first: every code path a peer takes has run once (sanitizers need file
     // descriptors to check some things the first time, and there will be none to spare).
    auto warm = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 3000);
    warm->send(net::encodeMessage(1, wholeScreen()));
    ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.framesPresented == 1; }));
  }
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &old), 0);
  // Room for a few more descriptors than this process holds now: the flood exhausts them.
  int open = 0;
  for (int fd = 0; fd < 4096; ++fd) open += ::fcntl(fd, F_GETFD) != -1;
  rlimit tight = old;
  tight.rlim_cur = rlim_t(open + 24);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &tight), 0);
  std::vector<int> flood;
  for (int i = 0; i < 20; ++i)
    if (const int fd = rawConnect(sink.port()); fd >= 0) flood.push_back(fd);
  const bool failed = sink.waitForLog("cannot accept a peer");
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &old), 0);
  EXPECT_TRUE(failed) << sink.log();
  // Once the flood is released, a real peer still gets in: the accept loop went on after the
  // error (it used to end there for good).
  for (const int fd : flood) ::close(fd);
  auto good = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 3000);
  good->send(net::encodeMessage(2, wholeScreen()));
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.framesPresented == 2; }))
      << sink.log();
}

TEST(SinkHardening, DropsPeersThatSayNoHelloAndCapsConnections) {
  auto s = test::twoDisplaySink();
  s.helloTimeoutMs = 200;
  s.maxPeers = 2;
  test::SinkRunner sink(s);
  const int a = rawConnect(sink.port()), b = rawConnect(sink.port());
  ASSERT_GE(a, 0);
  ASSERT_GE(b, 0);
  const int c = rawConnect(sink.port());  // the third is over --max-peers (accepted in order)
  ASSERT_GE(c, 0);
  // One is refused for the cap, two are dropped for saying no Hello within 200 ms: the log says
  // which happened.
  EXPECT_TRUE(closedWithin(c, 10000));
  EXPECT_TRUE(closedWithin(a, 10000));
  EXPECT_TRUE(closedWithin(b, 10000));
  for (const int fd : {a, b, c}) ::close(fd);
  EXPECT_NE(sink.log().find("sent no Hello within 200 ms"), std::string::npos) << sink.log();
  EXPECT_NE(sink.log().find("peers connected (--max-peers)"), std::string::npos) << sink.log();
  EXPECT_NO_THROW(net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 2000));
}

// 256 connections that never said Hello (re-opened as they were dropped) left no place for a
// render job's ranks. One address now holds at most 16 such connections, and the refusals are
// counted in the log instead of a line each.
TEST(SinkHardening, SilentConnectionsFromOneHostLeaveRoomForAnother) {
  test::SinkRunner sink(test::twoDisplaySink());
  std::vector<int> silent;
  for (int i = 0; i < 300; ++i) {
    const int fd = rawConnect(sink.port(), "127.0.0.2");
    ASSERT_GE(fd, 0);
    silent.push_back(fd);
  }
  EXPECT_TRUE(sink.waitForLog("connections from 127.0.0.2 have not said Hello")) << sink.log();
  auto rank = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 2000);
  rank->send(net::encodeMessage(0, wholeScreen()));
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.framesPresented == 1; }))
      << sink.log();
  const std::string log = sink.log();
  int lines = 0;
  for (auto at = log.find("have not said Hello"); at != std::string::npos;
       at = log.find("have not said Hello", at + 1))
    ++lines;
  EXPECT_LE(lines, 2) << log;  // 284 refusals, told at most once every 10 s
  for (const int fd : silent) ::close(fd);
}

// a header claiming 64 MiB was allocated and zeroed before Hello or any payload.
TEST(SinkHardening, RefusesALargePayloadBeforeHello) {
  test::SinkRunner sink(test::twoDisplaySink());
  const int fd = rawConnect(sink.port());
  ASSERT_GE(fd, 0);
  auto hello = net::encodeMessage(rendererHello(0, 1));
  const std::uint32_t claimed = 64u << 20;
  std::memcpy(hello.data() + 12, &claimed, 4);
  const std::uint32_t checksum = XXH32(hello.data(), 28, 0);
  std::memcpy(hello.data() + 28, &checksum, 4);
  (void)!::send(fd, hello.data(), net::kHeaderBytes, MSG_NOSIGNAL);
  EXPECT_TRUE(closedWithin(fd, 2000));
  ::close(fd);
  EXPECT_NE(sink.log().find("before its Hello"), std::string::npos) << sink.log();
}

// ten one-pixel tiles for ten frames held ten wall-sized pictures (490 MB on bigeye).
TEST(SinkHardening, OpenFramesHoldWhatArrivedNotAWallEach) {
  const auto wall = walls::loadWall(VOXWALL_WALLS_DIR "/bigeye.json");
  std::vector<walls::FrameEvent> events;
  walls::FrameAssembler assembler(wall, {10, 0, walls::kDefaultFrameWindow},
                                  [&](const walls::FrameEvent& e) { events.push_back(e); });
  std::uint64_t peak = 0;
  for (std::uint64_t f = 0; f < 10; ++f) {
    EXPECT_FALSE(assembler.addTile(f, solidTileMessage({int(f), 0, 1, 1}, 0xff), 0, "t"));
    peak = std::max(peak, assembler.heldBytes());
  }
  // A coverage bit per screen pixel and the tile with its bookkeeping: about 3 MiB a frame on
  // bigeye.
  const std::uint64_t bitmap = (std::uint64_t(wall.width) * std::uint64_t(wall.height) + 63) / 8;
  EXPECT_LE(peak, 10 * (bitmap + 128));
  EXPECT_TRUE(events.empty());
}

TEST(SinkHardening, OpenFramesStayUnderTheMemoryLimit) {
  const auto wall =
      test::twoDisplayWall();  // 44x10: one frame = 1760 bytes of pixels + 56 of bitmap
  std::vector<walls::FrameEvent> events;
  walls::FrameAssembler assembler(wall, {64, 4000, walls::kDefaultFrameWindow},
                                  [&](const walls::FrameEvent& e) { events.push_back(e); });
  for (std::uint64_t f = 0; f < 8; ++f) {
    assembler.addTile(f, solidTileMessage({0, 0, 22, 10}, 0xff), 0, "t");
    EXPECT_LE(assembler.heldBytes(), 4000u);
  }
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events[0].frame, 0u);
  EXPECT_NE(events[0].note.reason.find("memory limit"), std::string::npos);
  EXPECT_THROW(walls::FrameAssembler(wall, {4, 1000, 16}, {}), std::invalid_argument);
}

TEST(SinkHardening, FrameIdsOutsideTheJobsWindowAreRefused) {
  const auto wall = test::twoDisplayWall();
  std::vector<walls::FrameEvent> events;
  walls::FrameAssembler assembler(wall, {4, 0, 100},
                                  [&](const walls::FrameEvent& e) { events.push_back(e); });
  // Before any frame completed, the window starts at the job's first frame (0 here): a bogus
  // first frame cannot become the reference that keeps real ones out.
  EXPECT_FALSE(assembler.addTile(1'000'000, wholeScreen(), 0, "t"));
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].note.status, net::FrameStatus::Refused);
  EXPECT_NE(events[0].note.reason.find("where the job starts"), std::string::npos);
  // A frame far ahead but inside the window opens, and goes when frame 3 completes far behind.
  assembler.addTile(99, solidTileMessage({0, 0, 22, 10}, 0xff), 0, "t");
  EXPECT_TRUE(assembler.addTile(3, wholeScreen(), 0, "t"));
  EXPECT_EQ(assembler.openFrames(), 1u);  // 99 - 3 is inside the window
  EXPECT_TRUE(assembler.addTile(4, wholeScreen(), 0, "t"));
  EXPECT_FALSE(assembler.addTile(105, wholeScreen(), 0, "t"));  // 101 ahead of frame 4
  EXPECT_EQ(events.back().note.status, net::FrameStatus::Refused);
  // A new job starting at frame 500: its frame 10 is refused, its frame 500 shown.
  assembler.startSequence(500, "a new job");
  EXPECT_EQ(events.back().frame, 99u);  // the old job's open frame was dropped
  EXPECT_EQ(events.back().note.status, net::FrameStatus::Dropped);
  EXPECT_FALSE(assembler.addTile(10, wholeScreen(), 0, "t"));
  EXPECT_NE(events.back().note.reason.find("before frame 500"), std::string::npos);
  EXPECT_TRUE(assembler.addTile(500, wholeScreen(), 0, "t"));
}

// tokens compared with ==, in time that leaks the matching prefix.
TEST(SinkHardening, SecretsCompareWholly) {
  EXPECT_TRUE(walls::sameSecret("s3cret", "s3cret"));
  EXPECT_TRUE(walls::sameSecret("", ""));
  EXPECT_FALSE(walls::sameSecret("s3cret", "s3creT"));
  EXPECT_FALSE(walls::sameSecret("s3cret", "s3cre"));
  EXPECT_FALSE(walls::sameSecret("", "x"));
}

// a refused renderer kept rendering; refusal is now final and distinguishable.
TEST(SinkHardening, ARefusedStreamerStopsTryingAndSaysWhy) {
  auto s = test::twoDisplaySink();
  s.token = "right";
  test::SinkRunner sink(s);
  auto hello = rendererHello(0, 1);
  hello.token = "wrong";
  net::TileStreamer streamer("127.0.0.1", sink.port(), hello);
  EXPECT_FALSE(streamer.sendFrame(0, {}, 0));
  EXPECT_NE(streamer.refused().find("wrong token"), std::string::npos) << streamer.refused();
  EXPECT_EQ(streamer.connectAttempts(), 1);
  EXPECT_FALSE(streamer.sendFrame(1, {}, 0));
  EXPECT_EQ(streamer.connectAttempts(), 1);  // no second attempt
}

// Guessing the token gains nothing from speed: after a wrong token the address is refused unheard
// (even with the right token) for a back-off that doubles, and the log counts the guesses instead
// of a line each; once the back-off passed, the right token is accepted.
TEST(SinkHardening, WrongTokensBackOffPerAddressAndAreCountedNotLoggedEach) {
  auto s = test::twoDisplaySink();
  s.token = "right";
  test::SinkRunner sink(s);
  auto bad = rendererHello(0, 1);
  bad.token = "wrong";
  int heard = 0;  // wrong tokens the sink listened to; the others were refused unheard
  auto guess = [&] {
    net::TileStreamer streamer("127.0.0.1", sink.port(), bad);
    EXPECT_FALSE(streamer.sendFrame(0, {}, 0));
    const std::string why = streamer.refused();
    EXPECT_NE(why.find("wrong token"), std::string::npos) << why;
    if (why.find("too many wrong tokens") == std::string::npos) ++heard;
  };
  for (int i = 0; i < 40; ++i) guess();
  EXPECT_GE(sink.sink().stats().peersRefused, 40);
  // The back-off doubles with each wrong token heard: after six it is 3.2 s, so the right token
  // that follows at once is refused unheard however slow the machine (after one it is 0.1 s,
  // which 40 quick guesses can use up).
  EXPECT_TRUE(test::waitUntil([&] { return guess(), heard >= 6; }, std::chrono::seconds(60)));
  const std::string log = sink.log();
  int lines = 0;
  for (std::size_t at = log.find("wrong token ("); at != std::string::npos;
       at = log.find("wrong token (", at + 1))
    ++lines;
  EXPECT_GE(lines, 1) << log;
  EXPECT_LE(lines, 4) << log;
  auto good = rendererHello(0, 1);
  good.token = "right";
  {
    net::TileStreamer early("127.0.0.1", sink.port(), good);
    EXPECT_FALSE(early.sendFrame(0, {}, 0));
    EXPECT_NE(early.refused().find("too many wrong tokens from 127.0.0.1"), std::string::npos)
        << early.refused();
  }
  EXPECT_TRUE(test::waitUntil([&] {
    net::TileStreamer later("127.0.0.1", sink.port(), good);
    return later.sendFrame(0, {}, 0);
  })) << sink.log();
}

// frames appear whole (marker last); what a killed sink left is cleared at start.
TEST(SinkHardening, FrameFilesAppearWholeAndLeftoversAreCleared) {
  test::TempDir dir;
  const auto wall = test::twoDisplayWall();
  walls::FrameAssembler assembler(wall, {}, {});
  const auto frame = assembler.addTile(3, solidTileMessage({0, 0, 44, 10}, 0x604020), 0, "t");
  ASSERT_TRUE(frame.has_value());
  walls::FrameFileSettings files;
  files.mosaic = true;
  walls::writeFrameFiles(dir.path(""), wall, *frame, files);
  EXPECT_TRUE(walls::frameFilesComplete(dir.path(""), 3));
  EXPECT_TRUE(std::filesystem::exists(dir.path("frame_00003.done")));
  // As a sink killed mid-frame leaves it: one picture renamed, one temporary, no marker; a
  // render job's own frame (frame_N.png) in the same folder is not the sink's to remove.
  test::writeFile(dir.path("frame_00004_r0c0.png"), "whole");
  test::writeFile(dir.path("frame_00004_r0c1.png.tmp.77"), "half");
  test::writeFile(dir.path("frame_00004.png"), "a render job's frame");
  EXPECT_FALSE(walls::frameFilesComplete(dir.path(""), 4));
  EXPECT_EQ(walls::removeIncompleteFrames(dir.path("")), 2);
  EXPECT_TRUE(std::filesystem::exists(dir.path("frame_00004.png")));
  EXPECT_TRUE(walls::frameFilesComplete(dir.path(""), 3));
  // A picture changed after the marker no longer counts as complete.
  test::writeFile(dir.path("frame_00003_r0c0.png"), "cut");
  EXPECT_FALSE(walls::frameFilesComplete(dir.path(""), 3));
}

// A kind's first `burst` lines in 10 s are told, the rest counted and told with the next line.
TEST(LogThrottle, TellsABurstAWindowThenCountsWhatItDidNotTell) {
  walls::LogThrottle throttle(3);
  const auto t0 = walls::LogThrottle::Clock::now();
  for (int i = 0; i < 3; ++i) EXPECT_EQ(throttle.line("a", "x", t0), "x") << i;
  EXPECT_EQ(throttle.line("a", "x", t0 + std::chrono::seconds(9)), "");
  EXPECT_EQ(throttle.line("a", "x", t0 + std::chrono::seconds(9)), "");
  EXPECT_EQ(throttle.line("b", "y", t0 + std::chrono::seconds(9)), "y");  // kinds apart
  EXPECT_EQ(throttle.line("a", "x", t0 + std::chrono::seconds(10)),
            "x (and 2 more like it since the last such line)");
  EXPECT_EQ(throttle.line("a", "x", t0 + std::chrono::seconds(11)), "x");
}

namespace {

std::size_t countOf(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

// Garbage headers (11,227 log lines a second from one outsider before) and jobs of one Hello
// each, coming and going: every one is refused or counted, and the log tells at most 5 lines per
// kind every 10 s (bounded here by the time the test took, not timed).
TEST(SinkHardening, OutsidersCannotFloodTheLog) {
  auto s = test::twoDisplaySink();
  s.token = "right";
  test::SinkRunner sink(s);
  const auto start = std::chrono::steady_clock::now();
  std::byte garbage[net::kHeaderBytes];
  std::memset(garbage, 0x5a, sizeof garbage);
  for (int i = 0; i < 100; ++i) {
    const int fd = rawConnect(sink.port());
    ASSERT_GE(fd, 0);
    (void)!::send(fd, garbage, sizeof garbage, MSG_NOSIGNAL);
    EXPECT_TRUE(closedWithin(fd, 5000)) << i;
    ::close(fd);
  }
  auto hello = rendererHello(0, 1);
  hello.token = "right";
  for (int i = 0; i < 30; ++i) {
    hello.jobId = std::uint64_t(1000 + i);  // a new job each time, leaving at once
    net::Connection::open("127.0.0.1", sink.port(), hello, 2000);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::size_t windows = 1 + std::size_t(seconds / 10);
  EXPECT_GE(sink.sink().stats().peersRefused, 100);
  const std::string log = sink.log();
  const std::size_t told = countOf(log, "sink: refused") + countOf(log, "sink: dropped");
  EXPECT_GE(told, 1u) << log;
  EXPECT_LE(told, 2 * 5 * windows) << log;
  EXPECT_GE(countOf(log, "took the wall") + countOf(log, "started"), 1u) << log;
  EXPECT_LE(countOf(log, "took the wall") + countOf(log, "started"), 5 * windows) << log;
}

// Connections that said no Hello from a few addresses filled every place on the tile port
// (--max-peers) and a new render job could not connect. Now a rank comes in, in place of the
// oldest connection of the address holding the most that has not said Hello.
TEST(SinkHardening, ConnectionsWithoutAHelloMakeRoomForARank) {
  auto s = test::twoDisplaySink();
  s.maxPeers = 8;
  test::SinkRunner sink(s);
  std::vector<int> silent;
  for (int i = 0; i < 8; ++i) {
    silent.push_back(rawConnect(sink.port(), i < 4 ? "127.0.0.2" : "127.0.0.3"));
    ASSERT_GE(silent.back(), 0);
  }
  auto rank = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 2000);
  rank->send(net::encodeMessage(0, wholeScreen()));
  EXPECT_TRUE(sink.waitForLog("frame 0 presented")) << sink.log();
  EXPECT_TRUE(closedWithin(silent.front(), 5000));
  EXPECT_NE(sink.log().find("replaced by a newer connection"), std::string::npos) << sink.log();
  for (const int fd : silent) ::close(fd);
}

// A peer of the job saying it abandoned frames 0..4095 settled every frame of the window as
// superseded before it was sent (0 of 300 presented, a line each). Now a FrameEnd supersedes
// only a frame that is open or among the next 16 in flight, and only for its sender's own rank.
TEST(SinkHardening, AbandoningFramesFarAheadSettlesNoneOfThem) {
  test::SinkRunner sink(test::twoDisplaySink());
  auto rank = net::Connection::open("127.0.0.1", sink.port(), rendererHello(0, 1), 2000);
  for (std::uint64_t f = 0; f < 4096; ++f)
    rank->send(net::encodeMessage(f, net::FrameEnd{0, 0, true}));
  rank->send(net::encodeMessage(100, wholeScreen()));
  ASSERT_TRUE(sink.waitForLog("frame 100 presented")) << sink.log();
  EXPECT_EQ(sink.sink().stats().framesSuperseded, 16);
  // Another rank's FrameEnd from this one is refused: the peer is dropped.
  rank->send(net::encodeMessage(101, net::FrameEnd{1, 0, true}));
  EXPECT_TRUE(sink.waitForLog("sent the FrameEnd of rank 1")) << sink.log();
}

// Segments that overlap or straddle display edges multiplied the bytes past --pending-mib (800
// overlapping segments of 61.6 MB went to the pages as 246.7 MB a frame; two 67 MB segments on
// bigeye peaked at 2.64 GB). A straddling segment now costs its bytes once per display it goes
// to, and tiles that cover their frame's screen more than twice over drop their peer.
TEST(SinkHardening, OverlappingAndStraddlingSegmentsCostWhatTheyMultiply) {
  const auto wall = test::twoDisplayWall();  // displays at x 0..20 and 24..44
  walls::FrameAssembler assembler(wall, {}, {});
  const auto before = assembler.heldBytes();
  const auto one = solidTileMessage({0, 0, 20, 10}, 0xff);          // on display 0 only
  const auto straddling = solidTileMessage({10, 0, 20, 10}, 0xff);  // on both
  assembler.addTile(1, one, 0, "t");
  const auto oneCost = assembler.heldBytes() - before;
  assembler.addTile(2, straddling, 0, "t");
  const auto straddlingCost = assembler.heldBytes() - before - oneCost;
  EXPECT_EQ(straddlingCost - oneCost, straddling.bytes.size());  // its bytes once more
  // Frame 3: 4 x 220 pixels are twice its 440; a fifth tile is refused and drops its peer.
  for (int i = 0; i < 4; ++i)
    EXPECT_NO_THROW(assembler.addTile(3, solidTileMessage({0, 0, 22, 10}, 0xff), 0, "t")) << i;
  EXPECT_THROW(assembler.addTile(3, solidTileMessage({0, 0, 22, 10}, 0xff), 0, "t"), FormatError);
}
