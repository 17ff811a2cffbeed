// The sink against well-behaved and badly behaved peers on loopback (port 0).
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <thread>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/frame_files.hpp>
#include <voxwall/walls/sink.hpp>

#include "support/sink_runner.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;

namespace {

using RunningSink = test::SinkRunner;
const auto testWall = test::twoDisplayWall;
const auto settings = [](const std::string& out = "") { return test::twoDisplaySink(out); };

// A raw TCP peer: sends whatever it is given and reads what comes back until the sink closes.
class RawPeer {
 public:
  explicit RawPeer(std::uint16_t port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  }
  ~RawPeer() { ::close(fd_); }
  bool connected() const { return connected_; }
  void send(const std::vector<std::byte>& bytes) {
    (void)!::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
  }
  // Everything the sink sent until it closed; `closed` says whether it did within 5 s.
  std::vector<std::byte> readUntilClosed(bool* closed) {
    std::vector<std::byte> all;
    *closed = false;
    for (int i = 0; i < 500; ++i) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 10) <= 0) continue;
      std::byte buf[4096];
      const auto n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        *closed = true;
        return all;
      }
      all.insert(all.end(), buf, buf + n);
    }
    return all;
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
};

std::string byeReason(const std::vector<std::byte>& bytes) {
  net::MessageReader reader("sink");
  reader.feed(bytes);
  while (auto m = reader.next())
    if (m->type == net::MessageType::Bye) return net::decodeBye(m->payload, "sink").reason;
  return "";
}

net::Hello renderer(int rank, int ranks, const std::string& token = "") {
  return net::Hello{net::Role::Renderer, rank, ranks, "t2x1", token};
}

// A solid tile of colour `rgb` (opaque) at `rect`.
net::EncodedTile solidTile(const voxwall::Rect& rect, std::uint32_t rgb) {
  voxwall::Image image(rect.width, rect.height);
  for (auto& p : image.pixels) p = rgb | 0xff000000u;
  net::TileCodecSettings s;
  s.codec = net::TileCodec::Raw;
  return net::encodeTiles(image, rect, {0, 0, 0}, s)[0];
}

}  // namespace

TEST(Sink, PresentsAFrameOnlyWhenEveryDisplayPixelHasArrived) {
  test::TempDir dir;
  RunningSink sink(settings(dir.path("out")));
  auto left = net::Connection::open("127.0.0.1", sink.port(), renderer(0, 2), 2000);
  auto right = net::Connection::open("127.0.0.1", sink.port(), renderer(1, 2), 2000);
  EXPECT_EQ(left->welcome().screenWidth, 44);
  // Frame 1: only the left half arrives.
  left->send(net::encodeMessage(
      1, net::TileMessage{
             {0, 0, 22, 10}, net::TileCodec::Raw, 0, solidTile({0, 0, 22, 10}, 0x0000ff).bytes}));
  // Frame 2: both halves (the bezel column 20..23 belongs to no display).
  for (auto& [c, rect, color] :
       {std::tuple{left.get(), voxwall::Rect{0, 0, 22, 10}, 0x00ff00u},
        std::tuple{right.get(), voxwall::Rect{22, 0, 22, 10}, 0xff0000u}}) {
    const auto tile = solidTile(rect, color);
    c->send(net::encodeMessage(2, net::TileMessage{rect, tile.codec, 0, tile.bytes}));
  }
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) {
    return s.framesPresented == 1 && s.framesWritten == 1;  // written off the presentation path
  })) << sink.log();
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesDropped == 1; }));
  EXPECT_FALSE(std::filesystem::exists(dir.path("out/frame_00001_r0c0.png")));
  const auto l = voxwall::readImage(dir.path("out/frame_00002_r0c0.png"));
  const auto r = voxwall::readImage(dir.path("out/frame_00002_r0c1.png"));
  ASSERT_EQ(l.width, 20);
  EXPECT_EQ(l.pixels[0], 0xff00ff00u);
  EXPECT_EQ(r.pixels[0], 0xffff0000u);  // 0xff0000 with red in the lowest byte: blue
  // Late tiles for a frame already settled are ignored, not presented. Frame 3 follows them on
  // the same connection, so once it is presented and written the sink has read them.
  left->send(net::encodeMessage(
      1, net::TileMessage{
             {22, 0, 22, 10}, net::TileCodec::Raw, 0, solidTile({22, 0, 22, 10}, 0xff).bytes}));
  for (auto& [c, rect] : {std::pair{left.get(), voxwall::Rect{0, 0, 22, 10}},
                          std::pair{right.get(), voxwall::Rect{22, 0, 22, 10}}}) {
    const auto tile = solidTile(rect, 0x808080);
    c->send(net::encodeMessage(3, net::TileMessage{rect, tile.codec, 0, tile.bytes}));
  }
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) {
    return s.framesPresented >= 2 && s.framesWritten >= 2;
  })) << sink.log();
  EXPECT_TRUE(std::filesystem::exists(dir.path("out/frame_00003_r0c0.png"))) << sink.log();
  EXPECT_FALSE(std::filesystem::exists(dir.path("out/frame_00001_r0c0.png")));
  EXPECT_EQ(sink.sink().stats().framesPresented, 2);
}

// Frames that never complete are held up to --pending; then the oldest goes, reported.
TEST(Sink, DropsTheOldestWhenTooManyFramesAreOpen) {
  auto s = settings();
  s.pendingFrames = 2;
  RunningSink sink(s);
  auto c = net::Connection::open("127.0.0.1", sink.port(), renderer(0, 1), 2000);
  const auto half = solidTile({0, 0, 22, 10}, 0x123456);
  for (std::uint64_t frame : {1, 2, 3})
    c->send(net::encodeMessage(frame, net::TileMessage{half.rect, half.codec, 0, half.bytes}));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.framesDropped == 1; }))
      << sink.log();
  EXPECT_NE(sink.log().find("frame 1 dropped: too many frames open"), std::string::npos)
      << sink.log();
  EXPECT_EQ(sink.sink().stats().framesPresented, 0);
}

// Rank 0 hears whether the sink presented any frame of its job (a job none of whose frames was
// presented fails): frames dropped are noted but not presented; a whole frame is.
TEST(Sink, TheControllerHearsWhetherAFrameWasPresented) {
  auto s = settings();
  s.pendingFrames = 2;
  RunningSink sink(s);
  net::ControlChannel channel("127.0.0.1", sink.port(), renderer(0, 1));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& st) { return st.controllerConnected; }));
  auto c = net::Connection::open("127.0.0.1", sink.port(), renderer(0, 1), 2000);
  const auto half = solidTile({0, 0, 22, 10}, 0x123456);
  for (std::uint64_t frame : {1, 2, 3})
    c->send(net::encodeMessage(frame, net::TileMessage{half.rect, half.codec, 0, half.bytes}));
  EXPECT_FALSE(channel.waitForPresented(1, std::chrono::seconds(10)));  // frame 1 dropped
  EXPECT_EQ(channel.framesPresented(), 0u);
  const auto whole = solidTile({0, 0, 44, 10}, 0x808080);
  c->send(net::encodeMessage(4, net::TileMessage{whole.rect, whole.codec, 0, whole.bytes}));
  EXPECT_TRUE(channel.waitForPresented(100, std::chrono::seconds(10))) << sink.log();
  // A controller that connects once the frames were shown (it replaces the first) hears of the
  // last one at once.
  net::ControlChannel late("127.0.0.1", sink.port(), renderer(0, 1));
  EXPECT_TRUE(late.waitForPresented(1000, std::chrono::seconds(10))) << sink.log();
}

// A frame the render job abandoned (the camera moved while it rendered) is dropped as
// superseded, whichever rank says so first; its late tiles do not bring it back, the next frame
// is shown, and a controller cannot abandon frames.
TEST(Sink, AnAbandonedFrameIsDroppedAsSupersededAndStaysDropped) {
  RunningSink sink(settings());
  auto left = net::Connection::open("127.0.0.1", sink.port(), renderer(0, 2), 2000);
  auto right = net::Connection::open("127.0.0.1", sink.port(), renderer(1, 2), 2000);
  const auto l = solidTile({0, 0, 22, 10}, 0x123456), r = solidTile({22, 0, 22, 10}, 0x654321);
  left->send(net::encodeMessage(1, net::TileMessage{l.rect, l.codec, 0, l.bytes}));
  left->send(net::encodeMessage(1, net::FrameEnd{0, 1, false}));
  right->send(net::encodeMessage(1, net::FrameEnd{1, 0, true}));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesSuperseded == 1; }))
      << sink.log();
  EXPECT_NE(sink.log().find("frame 1 superseded: the render job abandoned it"), std::string::npos)
      << sink.log();
  right->send(net::encodeMessage(1, net::TileMessage{{22, 0, 22, 10}, r.codec, 0, r.bytes}));
  for (auto* c : {left.get(), right.get()}) {
    const auto& t = c == left.get() ? l : r;
    const voxwall::Rect rect =
        c == left.get() ? voxwall::Rect{0, 0, 22, 10} : voxwall::Rect{22, 0, 22, 10};
    c->send(net::encodeMessage(2, net::TileMessage{rect, t.codec, 0, t.bytes}));
  }
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 1; }))
      << sink.log();
  const auto stats = sink.sink().stats();
  EXPECT_EQ(stats.framesSuperseded, 1);
  EXPECT_EQ(stats.framesDropped, 0);
  EXPECT_EQ(sink.log().find("frame 1 presented"), std::string::npos) << sink.log();
  net::Hello control = renderer(0, 2);
  control.role = net::Role::Controller;
  auto controller = net::Connection::open("127.0.0.1", sink.port(), control, 2000);
  controller->send(net::encodeMessage(3, net::FrameEnd{0, 0, true}));
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.peersDropped == 1; }));
  EXPECT_NE(sink.log().find("a controller sent a FrameEnd"), std::string::npos) << sink.log();
}

TEST(Sink, RefusesWrongTokenVersionAndWall) {
  auto s = settings();
  s.token = "secret";
  RunningSink sink(s);
  auto otherWall = renderer(0, 1, "secret");
  otherWall.wallId = "bigeye";
  try {
    net::Connection::open("127.0.0.1", sink.port(), otherWall, 2000);
    ADD_FAILURE() << "a peer for another wall got in";
  } catch (const net::NetError& e) {
    EXPECT_NE(std::string(e.what()).find("renders for wall \"bigeye\""), std::string::npos)
        << e.what();
  }
  for (int version : {0, net::kWireVersion - 1, net::kWireVersion + 1}) {
    if (version == net::kWireVersion) continue;
    auto hello = net::encodeMessage(renderer(0, 1, "secret"));
    const std::uint16_t v = std::uint16_t(version);
    std::memcpy(hello.data() + 4, &v, 2);
    RawPeer peer(sink.port());
    ASSERT_TRUE(peer.connected());
    peer.send(hello);
    bool closed = false;
    const auto reason = byeReason(peer.readUntilClosed(&closed));
    EXPECT_TRUE(closed);
    EXPECT_NE(reason.find("protocol version"), std::string::npos) << "'" << reason << "'";
  }
  for (int i = 0; i < 2; ++i) {
    try {
      net::Connection::open("127.0.0.1", sink.port(), renderer(0, 1, "guess"), 2000);
      ADD_FAILURE() << "a wrong token got in";
    } catch (const net::NetError& e) {
      EXPECT_NE(std::string(e.what()).find("wrong token"), std::string::npos) << e.what();
    }
  }
  // The right token gets in once the address's back-off after the wrong one has passed.
  EXPECT_TRUE(test::waitUntil([&] {
    try {
      net::Connection::open("127.0.0.1", sink.port(), renderer(0, 1, "secret"), 2000);
      return true;
    } catch (const net::NetError&) {
      return false;
    }
  }));
  EXPECT_GE(sink.sink().stats().peersRefused, 5);
}

TEST(Sink, SurvivesGarbageTruncationAndOversizedLengths) {
  RunningSink sink(settings());
  {  // garbage
    RawPeer peer(sink.port());
    std::vector<std::byte> garbage(100);
    for (std::size_t i = 0; i < garbage.size(); ++i) garbage[i] = std::byte(i * 7 + 1);
    peer.send(garbage);
    bool closed = false;
    peer.readUntilClosed(&closed);
    EXPECT_TRUE(closed);
  }
  {  // an oversized length after a good Hello
    RawPeer peer(sink.port());
    peer.send(net::encodeMessage(renderer(0, 1)));
    auto big = net::encodeMessage(1, net::FrameEnd{0, 1});
    const std::uint32_t huge = net::kMaxPayload + 1;
    std::memcpy(big.data() + 12, &huge, 4);
    peer.send(big);
    bool closed = false;
    peer.readUntilClosed(&closed);
    EXPECT_TRUE(closed);
  }
  {  // a tile before Hello
    RawPeer peer(sink.port());
    peer.send(net::encodeMessage(1, net::FrameEnd{0, 1}));
    bool closed = false;
    EXPECT_NE(byeReason(peer.readUntilClosed(&closed)).find("before Hello"), std::string::npos);
    EXPECT_TRUE(closed);
  }
  {  // a tile cut off in the middle, then the peer vanishes
    RawPeer peer(sink.port());
    peer.send(net::encodeMessage(renderer(0, 1)));
    auto tile = net::encodeMessage(
        3, net::TileMessage{
               {0, 0, 44, 10}, net::TileCodec::Raw, 0, solidTile({0, 0, 44, 10}, 0xff).bytes});
    tile.resize(tile.size() / 2);
    peer.send(tile);
  }
  {  // a tile whose pixels do not decode, and one outside the screen
    auto c = net::Connection::open("127.0.0.1", sink.port(), renderer(0, 1), 2000);
    c->send(net::encodeMessage(
        4,
        net::TileMessage{
            {0, 0, 44, 10}, net::TileCodec::Jpeg, 0, std::vector<std::byte>(300, std::byte{1})}));
    EXPECT_THROW(
        {
          for (int i = 0; i < 50; ++i) {
            c->receive(20);
          }
        },
        net::NetError);
  }
  // Garbage, the oversized length and the early tile are refused (with a Bye where the header
  // was readable); the half tile and the bad JPEG drop their connections.
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) {
    return s.peersRefused >= 3 && s.peersDropped >= 2;
  })) << sink.log();
  // Still serving: a whole frame from a good peer is presented.
  auto good = net::Connection::open("127.0.0.1", sink.port(), renderer(0, 1), 2000);
  const auto tile = solidTile({0, 0, 44, 10}, 0x808080);
  good->send(net::encodeMessage(9, net::TileMessage{tile.rect, tile.codec, 0, tile.bytes}));
  EXPECT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 1; }))
      << sink.log();
  EXPECT_EQ(sink.sink().stats().framesPresented, 1);
}

TEST(Sink, ForwardsCameraCommandsToTheController) {
  RunningSink sink(settings());
  net::ControlChannel channel("127.0.0.1", sink.port(), renderer(0, 1));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }));
  sink.sink().sendControl(walls::parseControlLine("rotate 30 -5"));
  sink.sink().sendControl(walls::parseControlLine("zoom 1.5"));
  std::vector<net::Control> got;
  test::waitUntil([&] {
    auto more = channel.drain();
    got.insert(got.end(), more.begin(), more.end());
    return got.size() >= 2;
  });
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].command, net::ControlCommand::Rotate);
  EXPECT_EQ(got[0].b, -5);
  EXPECT_EQ(got[1].command, net::ControlCommand::Zoom);
  EXPECT_THROW(walls::parseControlLine("spin 3"), std::invalid_argument);
  EXPECT_THROW(walls::parseControlLine("zoom -1"), std::invalid_argument);
  // Numbers are decimal: hexadecimal, inf and nan are not numbers; a value too small for a
  // double is a number (refused by the command's own range).
  for (const char* line : {"seek 0x10", "zoom inf", "pan nan 0", "zoom 1.5f", "rotate 1,5 0"}) {
    try {
      walls::parseControlLine(line);
      ADD_FAILURE() << line;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("is not a number"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(walls::parseControlLine("pan -.5 +2e-3").a, -0.5);
  try {
    walls::parseControlLine("zoom 4.9e-324");
    ADD_FAILURE() << "a denormal zoom factor was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("zoom takes a factor from 0.001 to 1000"),
              std::string::npos)
        << e.what();
  }
}

// A job of one volume has no time: once it presented a frame without telling a time series,
// play, pause, step and seek are refused at the sink in one line (they were taken as steering:
// `seek 0` every 0.3 s reduced every frame); camera commands still go.
TEST(Sink, TimeCommandsForAJobOfOneVolumeAreRefused) {
  RunningSink sink(settings());
  auto hello = renderer(0, 1);
  hello.jobId = 41;
  net::ControlChannel channel("127.0.0.1", sink.port(), hello);
  auto rank = net::Connection::open("127.0.0.1", sink.port(), hello, 2000);
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }));
  const auto tile = solidTile({0, 0, 44, 10}, 0x808080);
  rank->send(net::encodeMessage(0, net::TileMessage{tile.rect, tile.codec, 0, tile.bytes}));
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.framesPresented == 1; }))
      << sink.log();
  // (The sink settles the frame in the same io-thread step that counts it presented; commands
  // are posted to that thread after it.)
  for (const char* line : {"seek 0", "step 1", "play", "rotate 5 0"})
    sink.sink().sendControl(walls::parseControlLine(line));
  std::vector<net::Control> got;
  test::waitUntil([&] {
    auto more = channel.drain();
    got.insert(got.end(), more.begin(), more.end());
    return !got.empty();
  });
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].command, net::ControlCommand::Rotate);
  EXPECT_NE(sink.log().find("sink: the job renders one volume: play, pause, step and seek have "
                            "no time to move"),
            std::string::npos)
      << sink.log();
}

// Time commands: a page's or stdin's play, pause, step and seek reach rank 0, and rank 0's
// Playback reaches the sink's statistics (the pages read it there); a new job clears it, and a
// renderer may not send one.
TEST(Sink, TimeCommandsReachTheControllerAndItsPlaybackReachesTheSink) {
  using C = net::ControlCommand;
  EXPECT_EQ(walls::parseControlLine("play"), (net::Control{C::Play, 0, 0}));
  EXPECT_EQ(walls::parseControlLine("pause"), (net::Control{C::Pause, 0, 0}));
  EXPECT_EQ(walls::parseControlLine("step -2"), (net::Control{C::StepBy, -2, 0}));
  EXPECT_EQ(walls::parseControlLine("seek 17"), (net::Control{C::Seek, 17, 0}));
  for (const char* bad :
       {"step 1.5", "step", "seek -1", "seek 65536", "play 3", "pause now", "step 1 2"})
    EXPECT_THROW(walls::parseControlLine(bad), std::invalid_argument) << bad;

  RunningSink sink(settings());
  auto hello = renderer(0, 1);
  hello.jobId = 31;
  net::ControlChannel channel("127.0.0.1", sink.port(), hello);
  ASSERT_TRUE(sink.waitFor([](const walls::SinkStats& s) { return s.controllerConnected; }));
  EXPECT_FALSE(sink.sink().stats().playback.has_value());
  const net::Playback playing{4, 2, 10, 2, true, 0};
  channel.setPlayback(3, playing);
  EXPECT_TRUE(sink.waitFor([&](const walls::SinkStats& s) { return s.playback == playing; }))
      << sink.log();
  for (const char* line : {"pause", "step 1", "seek 8", "play"})
    sink.sink().sendControl(walls::parseControlLine(line));
  std::vector<net::Control> got;
  test::waitUntil([&] {
    auto more = channel.drain();
    got.insert(got.end(), more.begin(), more.end());
    return got.size() >= 4;
  });
  ASSERT_EQ(got.size(), 4u);
  EXPECT_EQ(got[0].command, C::Pause);
  EXPECT_EQ(got[1], (net::Control{C::StepBy, 1, 0}));
  EXPECT_EQ(got[2], (net::Control{C::Seek, 8, 0}));
  EXPECT_EQ(got[3].command, C::Play);
  const net::Playback paused{6, 2, 10, 2, false, 0};
  channel.setPlayback(4, paused);
  EXPECT_TRUE(sink.waitFor([&](const walls::SinkStats& s) { return s.playback == paused; }));

  // A renderer that sends a Playback breaks the protocol: it is dropped, the state stays.
  auto rank = net::Connection::open("127.0.0.1", sink.port(), hello, 2000);
  const int dropped = sink.sink().stats().peersDropped;
  rank->send(net::encodeMessage(5, net::Playback{2, 2, 10, 2, true, 0}));
  EXPECT_TRUE(sink.waitFor([&](const walls::SinkStats& s) { return s.peersDropped > dropped; }));
  EXPECT_EQ(sink.sink().stats().playback, paused);
}

// A command is its whole line: trailing text, missing numbers or numbers with junk are refused,
// and the refusal quotes the line so that it cannot forge a log line or drive a terminal.
TEST(Sink, ControlLinesAreParsedWholeAndQuotedWhenRefused) {
  const auto ok = walls::parseControlLine(" \trotate  30\t-5 ");
  EXPECT_EQ(ok.command, net::ControlCommand::Rotate);
  EXPECT_EQ(ok.a, 30);
  EXPECT_EQ(ok.b, -5);
  EXPECT_EQ(walls::parseControlLine("pan 0.25 -1e-1").b, -0.1);
  EXPECT_EQ(walls::parseControlLine("reset").command, net::ControlCommand::Reset);
  for (const char* bad : {"zoom 2abc", "rotate 1 2 3 extra", "rotate 1", "reset now", "pan 1e7 0",
                          "zoom nan", "rotate inf 0", "zoom 0", "", "pan 1,2"})
    EXPECT_THROW(walls::parseControlLine(bad), std::invalid_argument) << bad;
  try {
    walls::parseControlLine("zoom 2\nsink: frame 999999 presented: 4/4 displays\x1b[2J");
    ADD_FAILURE() << "a forged line was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_EQ(what.find('\x1b'), std::string::npos) << what;
    EXPECT_NE(what.find("\\x0asink: frame 999999"), std::string::npos) << what;
  }
}

// Edge-blended projectors (a Tide surface with a negative bezel): both displays show the shared
// columns, the frame completes once every display's pixels are there, and each display's file
// holds the shared pixels.
TEST(FrameAssembler, OverlappingDisplaysCompleteAndShareTheirPixels) {
  const auto wall = walls::parseWall(R"({"surfaces": [{"displayWidth": 40, "displayHeight": 20,
      "screenCountX": 2, "bezelWidth": -8}]})",
                                     "blend.json");
  ASSERT_TRUE(wall.overlapping);
  ASSERT_EQ(wall.width, 72);
  std::vector<walls::FrameEvent> events;
  walls::FrameAssembler assembler(wall, {},
                                  [&](const walls::FrameEvent& e) { events.push_back(e); });
  // A different colour in every column, so shared pixels can be told apart from neighbours.
  auto columnTile = [](const voxwall::Rect& rect) {
    voxwall::Image image(rect.width, rect.height);
    for (int y = 0; y < rect.height; ++y)
      for (int x = 0; x < rect.width; ++x) image.at(x, y) = 0xff000000u | std::uint32_t(rect.x + x);
    net::TileCodecSettings s;
    s.codec = net::TileCodec::Raw;
    const auto tile = net::encodeTiles(image, rect, {0, 0, 0}, s)[0];
    return net::TileMessage{tile.rect, tile.codec, 0, tile.bytes};
  };
  // The left display and the shared columns: the right display still misses 32 columns.
  EXPECT_FALSE(assembler.addTile(0, columnTile({0, 0, 40, 20}), 0, "rank 0").has_value());
  const auto frame = assembler.addTile(0, columnTile({40, 0, 32, 20}), 1, "rank 1");
  ASSERT_TRUE(frame.has_value());
  EXPECT_TRUE(events.empty());

  test::TempDir dir;
  walls::writeFrameFiles(dir.root().string(), wall, *frame, {});
  const auto left = voxwall::readImage(dir.path("frame_00000_s0-0.png"));
  const auto right = voxwall::readImage(dir.path("frame_00000_s1-0.png"));
  ASSERT_EQ(left.width, 40);
  ASSERT_EQ(right.width, 40);
  for (int x = 0; x < 8; ++x) {  // screen columns 32..39 are in both
    EXPECT_EQ(left.at(32 + x, 5), right.at(x, 5)) << "shared column " << 32 + x;
    EXPECT_EQ(right.at(x, 5) & 0xffu, std::uint32_t(32 + x));
  }
}
