#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/wire.hpp>

namespace voxwall::net {
namespace {

using voxwall::ByteReader;
using voxwall::ByteWriter;

static_assert(kHeaderBytes == 4 + 2 + 2 + 4 + 4 + 8 + 4 + 4, "header layout");
// role, rank, rankCount, jobId, nextFrame, two strings at their limit
static_assert(1 + 4 + 4 + 8 + 8 + 2 * (2 + kMaxString) <= kMaxHelloPayload, "a Hello fits");

std::vector<std::byte> frameMessage(MessageType type, std::uint64_t frame,
                                    const std::vector<std::byte>& payload) {
  if (payload.size() > kMaxPayload) throw NetError("message payload over the protocol limit");
  std::vector<std::byte> out;
  out.reserve(kHeaderBytes + payload.size());
  ByteWriter w(out);
  w.put(kWireMagic);
  w.put(kWireVersion);
  w.put(std::uint16_t(type));
  w.put(std::uint32_t(0));
  w.put(std::uint32_t(payload.size()));
  w.put(frame);
  w.put(std::uint32_t(XXH32(payload.data(), payload.size(), 0)));
  w.put(std::uint32_t(XXH32(out.data(), 28, 0)));
  w.putBytes(payload);
  return out;
}

void putString(ByteWriter& w, const std::string& s) {
  if (s.size() > kMaxString) throw std::invalid_argument("string over the protocol limit");
  w.put(std::uint16_t(s.size()));
  w.putBytes(std::as_bytes(std::span(s)));
}

std::string getString(ByteReader& r) {
  const auto n = r.get<std::uint16_t>();
  if (n > kMaxString)
    r.fail("string of " + std::to_string(n) + " bytes (limit " + std::to_string(kMaxString) + ")");
  const auto b = r.getBytes(n);
  return std::string(reinterpret_cast<const char*>(b.data()), b.size());
}

void expectEnd(const ByteReader& r) {
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " trailing bytes");
}

}  // namespace

std::vector<std::byte> encodeMessage(const Hello& m) {
  std::vector<std::byte> p;
  ByteWriter w(p);
  w.put(std::uint8_t(m.role));
  w.put(std::int32_t(m.rank)), w.put(std::int32_t(m.rankCount));
  w.put(m.jobId), w.put(m.nextFrame);
  putString(w, m.wallId), putString(w, m.token);
  return frameMessage(MessageType::Hello, 0, p);
}

std::vector<std::byte> encodeMessage(const Welcome& m) {
  std::vector<std::byte> p;
  ByteWriter w(p);
  putString(w, m.wallId);
  w.put(std::int32_t(m.screenWidth)), w.put(std::int32_t(m.screenHeight));
  if (m.displays.size() > kMaxWelcomeDisplays)
    throw std::invalid_argument("Welcome: more displays than the protocol allows");
  w.put(std::uint8_t(m.bezels ? 1 : 0));
  w.put(std::uint16_t(m.displays.size()));
  for (const auto& d : m.displays) {
    w.put(std::int32_t(d.x)), w.put(std::int32_t(d.y));
    w.put(std::int32_t(d.width)), w.put(std::int32_t(d.height));
  }
  return frameMessage(MessageType::Welcome, 0, p);
}

std::vector<std::byte> encodeMessage(std::uint64_t frame, const TileMessage& m) {
  std::vector<std::byte> p;
  p.reserve(35 + m.bytes.size());
  ByteWriter w(p);
  w.put(std::int32_t(m.rect.x)), w.put(std::int32_t(m.rect.y));
  w.put(std::int32_t(m.rect.width)), w.put(std::int32_t(m.rect.height));
  w.put(std::uint8_t(m.codec));
  w.put(std::uint8_t(m.step));
  w.put(std::uint8_t(m.phase));
  w.put(m.decidedUnixMicros);
  w.put(m.renderMicros);
  w.putBytes(m.bytes);
  return frameMessage(MessageType::Tile, frame, p);
}

std::vector<std::byte> encodeMessage(std::uint64_t frame, const FrameEnd& m) {
  std::vector<std::byte> p;
  ByteWriter w(p);
  w.put(std::int32_t(m.rank)), w.put(m.tiles);
  w.put(std::uint8_t(m.abandoned ? 1 : 0));
  return frameMessage(MessageType::FrameEnd, frame, p);
}

std::vector<std::byte> encodeMessage(const Control& m) {
  std::vector<std::byte> p;
  ByteWriter w(p);
  w.put(std::uint8_t(m.command));
  w.put(m.a), w.put(m.b);
  return frameMessage(MessageType::Control, 0, p);
}

std::vector<std::byte> encodeMessage(const Bye& m) {
  std::vector<std::byte> p;
  ByteWriter w(p);
  putString(w, m.reason.substr(0, kMaxString));
  return frameMessage(MessageType::Bye, 0, p);
}

std::vector<std::byte> encodeMessage(std::uint64_t frame, const FrameNote& m) {
  std::vector<std::byte> p;
  ByteWriter w(p);
  w.put(std::uint8_t(m.status));
  putString(w, m.reason.substr(0, kMaxString));
  return frameMessage(MessageType::FrameNote, frame, p);
}

std::vector<std::byte> encodeKeepAlive() { return frameMessage(MessageType::KeepAlive, 0, {}); }

std::vector<std::byte> encodeMessage(std::uint64_t frame, const Playback& m) {
  std::vector<std::byte> p;
  ByteWriter w(p);
  w.put(m.step), w.put(m.first), w.put(m.last), w.put(m.stride);
  w.put(std::uint8_t(m.playing ? 1 : 0));
  w.put(m.rate);
  return frameMessage(MessageType::Playback, frame, p);
}

std::uint32_t checkHeader(std::span<const std::byte, kHeaderBytes> header,
                          const std::string& source, MessageType* type, std::uint64_t* frame) {
  ByteReader r(header, source, "message header");
  if (r.get<std::uint32_t>() != kWireMagic) r.fail("not a voxwall wall-protocol message");
  const auto version = r.get<std::uint16_t>();
  if (version != kWireVersion)
    r.fail("protocol version " + std::to_string(version) + ", this program speaks " +
           std::to_string(kWireVersion));
  const auto t = r.get<std::uint16_t>();
  if (t < 1 || t > 9) r.fail("unknown message type " + std::to_string(t));
  if (r.get<std::uint32_t>() != 0) r.fail("unknown flags");
  const auto length = r.get<std::uint32_t>();
  if (length > kMaxPayload)
    r.fail("payload of " + std::to_string(length) + " bytes (limit " + std::to_string(kMaxPayload) +
           ")");
  const auto f = r.get<std::uint64_t>();
  r.get<std::uint32_t>();  // payload checksum, checked with the payload
  const auto checksum = r.get<std::uint32_t>();
#ifndef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
  if (checksum != XXH32(header.data(), 28, 0)) r.fail("header checksum mismatch");
#else
  (void)checksum;
#endif
  if (type) *type = MessageType(t);
  if (frame) *frame = f;
  return length;
}

void checkPayload(std::span<const std::byte, kHeaderBytes> header,
                  std::span<const std::byte> payload, const std::string& source) {
#ifndef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
  std::uint32_t expected;
  std::memcpy(&expected, header.data() + 24, 4);
  if (XXH32(payload.data(), payload.size(), 0) != expected)
    throw FormatError(source, "payload checksum mismatch");
#else
  (void)header, (void)payload, (void)source;
#endif
}

Hello decodeHello(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "Hello");
  Hello m;
  const auto role = r.get<std::uint8_t>();
  if (role != 1 && role != 2) r.fail("unknown role " + std::to_string(role));
  m.role = Role(role);
  m.rank = r.get<std::int32_t>(), m.rankCount = r.get<std::int32_t>();
  if (m.rankCount < 1 || m.rankCount > (1 << 16) || m.rank < 0 || m.rank >= m.rankCount)
    r.fail("rank " + std::to_string(m.rank) + " of " + std::to_string(m.rankCount));
  m.jobId = r.get<std::uint64_t>();
  m.nextFrame = r.get<std::uint64_t>();
  m.wallId = getString(r), m.token = getString(r);
  expectEnd(r);
  return m;
}

Welcome decodeWelcome(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "Welcome");
  Welcome m;
  m.wallId = getString(r);
  m.screenWidth = r.get<std::int32_t>(), m.screenHeight = r.get<std::int32_t>();
  if (m.screenWidth <= 0 || m.screenHeight <= 0 || m.screenWidth > 65536 || m.screenHeight > 65536)
    r.fail("screen size");
  const auto flags = r.get<std::uint8_t>();
  if (flags > 1) r.fail("unknown flags " + std::to_string(flags));
  m.bezels = flags & 1;
  const auto count = r.get<std::uint16_t>();
  if (count > kMaxWelcomeDisplays)
    r.fail(std::to_string(count) + " displays (limit " + std::to_string(kMaxWelcomeDisplays) + ")");
  m.displays.resize(count);
  for (auto& d : m.displays) {
    d.x = r.get<std::int32_t>(), d.y = r.get<std::int32_t>();
    d.width = r.get<std::int32_t>(), d.height = r.get<std::int32_t>();
    if (!d.fitsIn(m.screenWidth, m.screenHeight)) r.fail("a display off the screen");
  }
  expectEnd(r);
  return m;
}

voxwall::Rect fullScreenRect(const voxwall::Rect& rect, int step, int screenWidth,
                             int screenHeight) {
  const long long x0 = std::min<long long>(std::int64_t(rect.x) * step, screenWidth);
  const long long y0 = std::min<long long>(std::int64_t(rect.y) * step, screenHeight);
  const long long x1 = std::min<long long>((std::int64_t(rect.x) + rect.width) * step, screenWidth);
  const long long y1 =
      std::min<long long>((std::int64_t(rect.y) + rect.height) * step, screenHeight);
  return {int(x0), int(y0), int(std::max(0LL, x1 - x0)), int(std::max(0LL, y1 - y0))};
}

TileMessage decodeTileMessage(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "Tile");
  TileMessage m;
  m.rect.x = r.get<std::int32_t>(), m.rect.y = r.get<std::int32_t>();
  m.rect.width = r.get<std::int32_t>(), m.rect.height = r.get<std::int32_t>();
  if (m.rect.x < 0 || m.rect.y < 0 || m.rect.width <= 0 || m.rect.height <= 0 ||
      m.rect.width > 16384 || m.rect.height > 16384)
    r.fail("tile rectangle " + std::to_string(m.rect.width) + "x" + std::to_string(m.rect.height) +
           "+" + std::to_string(m.rect.x) + "+" + std::to_string(m.rect.y));
  const auto codec = r.get<std::uint8_t>();
  if (codec < 1 || codec > 3) r.fail("unknown tile codec " + std::to_string(codec));
  m.codec = TileCodec(codec);
  m.step = r.get<std::uint8_t>();
  if (m.step < 1 || m.step > kMaxStep)
    r.fail("step " + std::to_string(m.step) + " (1.." + std::to_string(kMaxStep) + ")");
  const auto phase = r.get<std::uint8_t>();
  if (phase > 2) r.fail("unknown frame phase " + std::to_string(phase));
  m.phase = FramePhase(phase);
  m.decidedUnixMicros = r.get<std::uint64_t>();
  m.renderMicros = r.get<std::uint32_t>();
  const auto rest = r.getBytes(r.remaining());
  m.bytes.assign(rest.begin(), rest.end());
  return m;
}

FrameEnd decodeFrameEnd(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "FrameEnd");
  FrameEnd m;
  m.rank = r.get<std::int32_t>();
  m.tiles = r.get<std::uint32_t>();
  if (m.rank < 0) r.fail("negative rank");
  const auto flags = r.get<std::uint8_t>();
  if (flags > 1) r.fail("unknown flags " + std::to_string(flags));
  m.abandoned = flags & 1;
  expectEnd(r);
  return m;
}

std::string controlProblem(const Control& m) {
  if (!std::isfinite(m.a) || !std::isfinite(m.b) || std::abs(m.a) > 1e6 || std::abs(m.b) > 1e6)
    return "control values out of range";
  const double steps = double(kMaxPlaybackStep);
  switch (m.command) {
    case ControlCommand::Zoom:
      // A factor far from 1 (a denormal, 1e6) would put the camera at a distance no frame
      // shows anything from.
      if (!(m.a >= 1e-3 && m.a <= 1e3)) return "zoom takes a factor from 0.001 to 1000";
      break;
    case ControlCommand::StepBy:
      if (m.a != std::trunc(m.a) || std::abs(m.a) > steps)
        return "step takes a whole number of steps within +-" + std::to_string(kMaxPlaybackStep);
      break;
    case ControlCommand::Seek:
      if (m.a != std::trunc(m.a) || m.a < 0 || m.a >= steps)
        return "seek takes a time step 0.." + std::to_string(kMaxPlaybackStep - 1);
      break;
    default:
      break;
  }
  return "";
}

Control decodeControl(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "Control");
  Control m;
  const auto c = r.get<std::uint8_t>();
  if (c < 1 || c > 8) r.fail("unknown control command " + std::to_string(c));
  m.command = ControlCommand(c);
  m.a = r.get<double>(), m.b = r.get<double>();
  if (const auto why = controlProblem(m); !why.empty()) r.fail(why);
  expectEnd(r);
  return m;
}

Bye decodeBye(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "Bye");
  Bye m;
  m.reason = getString(r);
  expectEnd(r);
  return m;
}

FrameNote decodeFrameNote(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "FrameNote");
  FrameNote m;
  const auto status = r.get<std::uint8_t>();
  if (status < 1 || status > 4) r.fail("unknown frame status " + std::to_string(status));
  m.status = FrameStatus(status);
  m.reason = getString(r);
  expectEnd(r);
  return m;
}

Playback decodePlayback(std::span<const std::byte> payload, const std::string& source) {
  ByteReader r(payload, source, "Playback");
  Playback m;
  m.step = r.get<std::uint32_t>(), m.first = r.get<std::uint32_t>();
  m.last = r.get<std::uint32_t>(), m.stride = r.get<std::uint32_t>();
  const auto flags = r.get<std::uint8_t>();
  m.rate = r.get<double>();
  expectEnd(r);
  if (m.last >= kMaxPlaybackStep || m.first > m.step || m.step > m.last || m.stride < 1 ||
      m.stride >= kMaxPlaybackStep)
    r.fail("time step " + std::to_string(m.step) + " of " + std::to_string(m.first) + ".." +
           std::to_string(m.last) + " stride " + std::to_string(m.stride) + " is not a range");
  if (flags > 1) r.fail("unknown flags " + std::to_string(flags));
  m.playing = flags & 1;
  if (!std::isfinite(m.rate) || m.rate < 0 || m.rate > 1e6) r.fail("rate out of range");
  return m;
}

std::string describe(std::uint64_t frame, const FrameNote& note) {
  static const char* const kWords[] = {"", "presented", "dropped", "refused", "superseded"};
  std::string line = "frame " + std::to_string(frame) + " " + kWords[int(note.status)];
  if (!note.reason.empty()) line += ": " + note.reason;
  return line;
}

const char* phaseName(FramePhase phase) {
  switch (phase) {
    case FramePhase::Full:
      return "full";
    case FramePhase::Interactive:
      return "interactive";
    case FramePhase::Refining:
      return "refining";
  }
  return "unknown";
}

std::string stepLabel(int step, FramePhase phase) {
  if (step <= 1) return "";
  return std::string(phase == FramePhase::Refining ? "refining" : "interactive") + " 1/" +
         std::to_string(step);
}

void MessageReader::feed(std::span<const std::byte> bytes) {
  if (start_ > 0 && start_ == buffer_.size()) buffer_.clear(), start_ = 0;
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

std::optional<Message> MessageReader::next() {
  if (buffered() < kHeaderBytes) return std::nullopt;
  const std::span<const std::byte, kHeaderBytes> header(buffer_.data() + start_, kHeaderBytes);
  Message m;
  const std::uint32_t length = checkHeader(header, source_, &m.type, &m.frame);
  if (buffered() < kHeaderBytes + length) return std::nullopt;
  const std::span<const std::byte> payload(buffer_.data() + start_ + kHeaderBytes, length);
  checkPayload(header, payload, source_);
  m.payload.assign(payload.begin(), payload.end());
  start_ += kHeaderBytes + length;
  if (start_ > (1u << 20) && start_ * 2 > buffer_.size()) {
    buffer_.erase(buffer_.begin(), buffer_.begin() + std::ptrdiff_t(start_));
    start_ = 0;
  }
  return m;
}

}  // namespace voxwall::net
