#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/net/wire.hpp>

using namespace voxwall;
using net::MessageType;

namespace {

std::vector<net::Message> readAll(const std::vector<std::byte>& stream, std::size_t chunk) {
  net::MessageReader reader("test");
  std::vector<net::Message> out;
  for (std::size_t i = 0; i < stream.size(); i += chunk) {
    reader.feed(std::span(stream).subspan(i, std::min(chunk, stream.size() - i)));
    while (auto m = reader.next()) out.push_back(std::move(*m));
  }
  return out;
}

template <typename T>
void poke(std::vector<std::byte>& bytes, std::size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof value);
}

std::vector<std::byte> sampleTile() {
  net::TileMessage t;
  t.rect = {10, 20, 30, 40};
  t.codec = net::TileCodec::Deflate;
  t.decidedUnixMicros = 123456789;
  t.bytes = {std::byte{1}, std::byte{2}, std::byte{3}};
  t.step = 4;
  t.renderMicros = 2500;
  t.phase = net::FramePhase::Refining;
  return net::encodeMessage(42, t);
}

}  // namespace

TEST(Wire, EveryMessageRoundTripsInAnyChunking) {
  std::vector<std::byte> stream;
  auto append = [&](const std::vector<std::byte>& m) {
    stream.insert(stream.end(), m.begin(), m.end());
  };
  net::Hello sent{net::Role::Renderer, 2, 4, "bigeye", "secret"};
  sent.jobId = 0x0123456789abcdefull;
  sent.nextFrame = 77;
  append(net::encodeMessage(sent));
  append(net::encodeMessage(net::Welcome{"bigeye", 5772, 4338, {{0, 0, 1920, 1080}}, false}));
  append(sampleTile());
  append(net::encodeMessage(42, net::FrameEnd{2, 7, true}));
  append(net::encodeMessage(net::Control{net::ControlCommand::Pan, 0.5, -0.25}));
  append(net::encodeMessage(net::Bye{"done"}));
  append(net::encodeMessage(43, net::FrameNote{net::FrameStatus::Refused, "out of the window"}));
  for (std::size_t chunk : {std::size_t(1), std::size_t(7), std::size_t(4096)}) {
    const auto m = readAll(stream, chunk);
    ASSERT_EQ(m.size(), 7u);
    const auto hello = net::decodeHello(m[0].payload, "t");
    EXPECT_EQ(hello.rank, 2);
    EXPECT_EQ(hello.rankCount, 4);
    EXPECT_EQ(hello.wallId, "bigeye");
    EXPECT_EQ(hello.token, "secret");
    EXPECT_EQ(hello.jobId, 0x0123456789abcdefull);
    EXPECT_EQ(hello.nextFrame, 77u);
    EXPECT_EQ(net::decodeWelcome(m[1].payload, "t").screenHeight, 4338);
    EXPECT_EQ(m[2].type, MessageType::Tile);
    EXPECT_EQ(m[2].frame, 42u);
    const auto tile = net::decodeTileMessage(m[2].payload, "t");
    EXPECT_EQ(tile.rect, (voxwall::Rect{10, 20, 30, 40}));
    EXPECT_EQ(tile.codec, net::TileCodec::Deflate);
    EXPECT_EQ(tile.decidedUnixMicros, 123456789u);
    EXPECT_EQ(tile.bytes.size(), 3u);
    EXPECT_EQ(tile.step, 4);
    EXPECT_EQ(tile.renderMicros, 2500u);
    EXPECT_EQ(tile.phase, net::FramePhase::Refining);
    EXPECT_EQ(net::decodeFrameEnd(m[3].payload, "t").tiles, 7u);
    EXPECT_TRUE(net::decodeFrameEnd(m[3].payload, "t").abandoned);
    const auto control = net::decodeControl(m[4].payload, "t");
    EXPECT_EQ(control.command, net::ControlCommand::Pan);
    EXPECT_EQ(control.b, -0.25);
    EXPECT_EQ(net::decodeBye(m[5].payload, "t").reason, "done");
    EXPECT_EQ(m[6].frame, 43u);
    const auto note = net::decodeFrameNote(m[6].payload, "t");
    EXPECT_EQ(note.status, net::FrameStatus::Refused);
    EXPECT_EQ(net::describe(m[6].frame, note), "frame 43 refused: out of the window");
  }
  auto note = net::encodeMessage(1, net::FrameNote{net::FrameStatus::Dropped, ""});
  std::vector<std::byte> p(note.begin() + net::kHeaderBytes, note.end());
  p[0] = std::byte{9};  // unknown status
  EXPECT_THROW(net::decodeFrameNote(p, "t"), FormatError);
  EXPECT_EQ(net::describe(12, {net::FrameStatus::Superseded, "the camera moved"}),
            "frame 12 superseded: the camera moved");
  // A FrameEnd with unknown flags, a tile of an unknown phase.
  auto end = net::encodeMessage(1, net::FrameEnd{0, 1, false});
  std::vector<std::byte> e(end.begin() + net::kHeaderBytes, end.end());
  e.back() = std::byte{2};
  EXPECT_THROW(net::decodeFrameEnd(e, "t"), FormatError);
  auto tile = sampleTile();
  std::vector<std::byte> t(tile.begin() + net::kHeaderBytes, tile.end());
  t[4 * 4 + 2] = std::byte{3};  // after the rectangle, the codec and the step
  EXPECT_THROW(net::decodeTileMessage(t, "t"), FormatError);
}

TEST(Wire, AWelcomeCarriesTheDisplaysAndWhetherBezelsAreWanted) {
  net::Welcome w{"bigeye", 5772, 4338, {{0, 0, 1920, 1080}, {1926, 0, 1920, 1080}}, false};
  const auto bytes = net::encodeMessage(w);
  net::MessageReader reader("t");
  reader.feed(bytes);
  const auto m = reader.next();
  ASSERT_TRUE(m.has_value());
  const auto back = net::decodeWelcome(m->payload, "t");
  EXPECT_EQ(back.displays, w.displays);
  EXPECT_FALSE(back.bezels);
  const auto cut = back.cut();
  EXPECT_EQ(cut.screenWidth, 5772);
  EXPECT_EQ(cut.displays.size(), 2u);
  // A display off the screen, unknown flags, a count past the limit, or a list cut short.
  auto payload = m->payload;
  auto withInt = [&](std::size_t at, std::int32_t v) {
    auto p = payload;
    std::memcpy(p.data() + at, &v, 4);
    return p;
  };
  const std::size_t first = 2 + 6 + 4 + 4 + 1 + 2;  // wall id, screen, flags, count
  EXPECT_THROW(net::decodeWelcome(withInt(first, 5000), "t"), FormatError);  // x + 1920 > 5772
  auto flags = payload;
  flags[2 + 6 + 8] = std::byte{6};
  EXPECT_THROW(net::decodeWelcome(flags, "t"), FormatError);
  auto count = payload;
  const std::uint16_t many = 2000;
  std::memcpy(count.data() + 2 + 6 + 8 + 1, &many, 2);
  EXPECT_THROW(net::decodeWelcome(count, "t"), FormatError);
  auto cutShort = payload;
  cutShort.resize(payload.size() - 4);
  EXPECT_THROW(net::decodeWelcome(cutShort, "t"), FormatError);
}

TEST(Wire, TruncatedStreamsWaitForMoreAndNeverYieldHalfAMessage) {
  const auto tile = sampleTile();
  for (std::size_t n = 0; n < tile.size(); ++n) {
    net::MessageReader reader("test");
    reader.feed(std::span(tile).first(n));
    EXPECT_FALSE(reader.next().has_value()) << n;
  }
}

TEST(Wire, PeersAtOtherVersionsAreRefusedByName) {
  for (int delta : {-1, +1}) {
    auto m = sampleTile();
    poke(m, 4, std::uint16_t(net::kWireVersion + delta));
    net::MessageReader reader("peer");
    reader.feed(m);
    try {
      reader.next();
      FAIL() << "version " << net::kWireVersion + delta << " accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("protocol version"), std::string::npos) << e.what();
    }
  }
  auto zero = sampleTile();
  poke(zero, 4, std::uint16_t(0));
  net::MessageReader reader("peer");
  reader.feed(zero);
  EXPECT_THROW(reader.next(), FormatError);
}

TEST(Wire, GarbageOversizedAndTamperedMessagesAreRejected) {
  auto expectBad = [](std::vector<std::byte> bytes, const char* what) {
    net::MessageReader reader("peer");
    reader.feed(bytes);
    EXPECT_THROW(reader.next(), FormatError) << what;
  };
  std::vector<std::byte> garbage(64);
  for (std::size_t i = 0; i < garbage.size(); ++i) garbage[i] = std::byte(i * 37 + 11);
  expectBad(garbage, "garbage");
  auto big = sampleTile();
  poke(big, 12, std::uint32_t(net::kMaxPayload + 1));
  expectBad(big, "oversized length");
  auto header = sampleTile();
  header[17] ^= std::byte{1};  // frame id changed: the header checksum no longer matches
  expectBad(header, "header checksum");
  auto payload = sampleTile();
  payload.back() ^= std::byte{0x40};
  expectBad(payload, "payload checksum");
  auto type = sampleTile();
  poke(type, 6, std::uint16_t(99));
  expectBad(type, "unknown type");
}

TEST(Wire, PayloadDecodersCheckEveryField) {
  EXPECT_THROW(net::decodeHello({}, "t"), FormatError);
  auto hello = net::encodeMessage(net::Hello{net::Role::Renderer, 0, 1, "w", ""});
  const std::span payload = std::span(hello).subspan(net::kHeaderBytes);
  std::vector<std::byte> p(payload.begin(), payload.end());
  p[0] = std::byte{9};  // role
  EXPECT_THROW(net::decodeHello(p, "t"), FormatError);
  p = {payload.begin(), payload.end()};
  poke(p, 1, std::int32_t(5));  // rank 5 of 1
  EXPECT_THROW(net::decodeHello(p, "t"), FormatError);
  p = {payload.begin(), payload.end()};
  poke(p, 25, std::uint16_t(60000));  // string longer than the limit (after the frame ids)
  EXPECT_THROW(net::decodeHello(p, "t"), FormatError);
  p = {payload.begin(), payload.end()};
  p.push_back(std::byte{0});
  EXPECT_THROW(net::decodeHello(p, "t"), FormatError);

  auto control = net::encodeMessage(net::Control{net::ControlCommand::Zoom, 2, 0});
  std::vector<std::byte> c(control.begin() + net::kHeaderBytes, control.end());
  poke(c, 1, -1.0);  // zoom factor must be positive
  EXPECT_THROW(net::decodeControl(c, "t"), FormatError);
  poke(c, 1, std::nan(""));
  EXPECT_THROW(net::decodeControl(c, "t"), FormatError);

  auto tile = sampleTile();
  std::vector<std::byte> t(tile.begin() + net::kHeaderBytes, tile.end());
  poke(t, 8, std::int32_t(0));  // zero width
  EXPECT_THROW(net::decodeTileMessage(t, "t"), FormatError);
  t.assign(tile.begin() + net::kHeaderBytes, tile.end());
  t[16] = std::byte{7};  // codec
  EXPECT_THROW(net::decodeTileMessage(t, "t"), FormatError);
  for (const int step : {0, net::kMaxStep + 1, 255}) {
    t.assign(tile.begin() + net::kHeaderBytes, tile.end());
    t[17] = std::byte(step);  // the step, after the codec
    try {
      net::decodeTileMessage(t, "t");
      ADD_FAILURE() << "step " << step << " accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("step " + std::to_string(step)), std::string::npos)
          << e.what();
    }
  }
}

// A reduced rectangle stands for its blocks of the virtual screen, clipped at the edges.
// The time series' messages: where the job is (Playback), and the time commands' bounds.
TEST(Wire, PlaybackAndTimeCommandsRoundTripAndAreBounded) {
  const net::Playback sent{7, 3, 11, 2, false, 2.5};
  const auto message = net::encodeMessage(90, sent);
  const auto m = readAll(message, 3);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].type, MessageType::Playback);
  EXPECT_EQ(m[0].frame, 90u);
  EXPECT_EQ(net::decodePlayback(m[0].payload, "t"), sent);
  const std::vector<std::byte> good(message.begin() + net::kHeaderBytes, message.end());
  // step, first, last, stride at 0, 4, 8, 12; flags at 16; rate at 17.
  const std::vector<std::pair<std::size_t, std::uint32_t>> badRanges = {
      {0, 2},       // step before first
      {0, 12},      // step after last
      {12, 0},      // stride 0
      {8, 70000}};  // last past the most steps a file holds
  for (const auto& [offset, value] : badRanges) {
    auto p = good;
    poke(p, offset, value);
    EXPECT_THROW(net::decodePlayback(p, "t"), FormatError) << offset << " = " << value;
  }
  auto p = good;
  p[16] = std::byte{2};  // unknown flag
  EXPECT_THROW(net::decodePlayback(p, "t"), FormatError);
  for (const double rate : {-1.0, std::nan(""), 1e7}) {
    p = good;
    poke(p, 17, rate);
    EXPECT_THROW(net::decodePlayback(p, "t"), FormatError) << rate;
  }
  p = good;
  p.push_back(std::byte{0});
  EXPECT_THROW(net::decodePlayback(p, "t"), FormatError);
  p.resize(good.size() - 1);
  EXPECT_THROW(net::decodePlayback(p, "t"), FormatError);

  using C = net::ControlCommand;
  for (const net::Control ok : {net::Control{C::Play, 0, 0}, net::Control{C::Pause, 0, 0},
                                net::Control{C::StepBy, -3, 0}, net::Control{C::Seek, 65535, 0}}) {
    const auto bytes = net::encodeMessage(ok);
    EXPECT_EQ(net::decodeControl(std::span(bytes).subspan(net::kHeaderBytes), "t"), ok);
  }
  for (const net::Control bad : {net::Control{C::StepBy, 1.5, 0}, net::Control{C::StepBy, 70000, 0},
                                 net::Control{C::Seek, -1, 0}, net::Control{C::Seek, 65536, 0},
                                 net::Control{C::Seek, 2.5, 0}}) {
    const auto bytes = net::encodeMessage(bad);
    EXPECT_THROW(net::decodeControl(std::span(bytes).subspan(net::kHeaderBytes), "t"), FormatError)
        << int(bad.command) << " " << bad.a;
    EXPECT_FALSE(net::controlProblem(bad).empty());
  }
  auto unknown = net::encodeMessage(net::Control{C::Play, 0, 0});
  std::vector<std::byte> u(unknown.begin() + net::kHeaderBytes, unknown.end());
  u[0] = std::byte{9};
  EXPECT_THROW(net::decodeControl(u, "t"), FormatError);
}

TEST(Wire, ReducedRectanglesMapOntoTheVirtualScreen) {
  EXPECT_EQ(net::reducedSide(5772, 4), 1443);
  EXPECT_EQ(net::reducedSide(4338, 4), 1085);
  EXPECT_EQ(net::fullScreenRect({0, 0, 10, 10}, 1, 100, 100), (voxwall::Rect{0, 0, 10, 10}));
  EXPECT_EQ(net::fullScreenRect({2, 3, 4, 5}, 4, 100, 100), (voxwall::Rect{8, 12, 16, 20}));
  // The last reduced column of a 4338-high screen covers rows 4336..4337 only.
  EXPECT_EQ(net::fullScreenRect({0, 1084, 1, 1}, 4, 5772, 4338), (voxwall::Rect{0, 4336, 4, 2}));
}

TEST(Wire, RandomCorruptionNeverCrashes) {
  const auto good = sampleTile();
  std::mt19937 rng(3);
  for (int trial = 0; trial < 3000; ++trial) {
    auto bytes = good;
    for (int k = 0; k < 2; ++k) bytes[rng() % bytes.size()] ^= std::byte(1 + rng() % 255);
    net::MessageReader reader("fuzz");
    reader.feed(bytes);
    try {
      if (auto m = reader.next()) net::decodeTileMessage(m->payload, "fuzz");
    } catch (const FormatError&) {
    }
  }
}

TEST(Wire, EndpointsParse) {
  EXPECT_EQ(net::parseEndpoint("127.0.0.1:7400", "--sink").second, 7400);
  EXPECT_EQ(net::parseEndpoint("[::1]:80", "--sink").first, "::1");
  for (const char* bad : {"7400", "host:", ":7400", "host:port", "host:70000"})
    EXPECT_THROW(net::parseEndpoint(bad, "--sink"), std::invalid_argument) << bad;
}
