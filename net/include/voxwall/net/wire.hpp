// The wall protocol: rendering ranks and the master talk to the sink over TCP.
//
// Every message is a 32-byte header and a payload (little-endian, field by field):
//   offset size
//        0    4  u32 magic 0x50575756 ("VWWP")
//        4    2  u16 protocol version (kWireVersion)
//        6    2  u16 message type (MessageType)
//        8    4  u32 flags (0)
//       12    4  u32 payload bytes (<= kMaxPayload)
//       16    8  u64 frame id (0 where no frame)
//       24    4  u32 xxHash32 (seed 0) of the payload
//       28    4  u32 xxHash32 (seed 0) of bytes 0..27
// Payloads (str = u16 length <= kMaxString, then bytes):
//   Hello    u8 role (1 renderer, 2 controller), i32 rank, i32 rankCount, u64 jobId,
//            u64 nextFrame, str wallId, str token         (at most kMaxHelloPayload bytes)
//   Welcome  str wallId, i32 screenWidth, i32 screenHeight, u8 flags (bit 0: send segments that
//            lie on no display), u16 display count (<= kMaxWelcomeDisplays), then per display
//            i32 x, y, width, height (virtual-screen pixels, on the screen)
//                                                        (sink -> peer, after Hello)
//   Tile     i32 x, y, width, height, u8 codec, u8 step (1..kMaxStep), u8 phase (FramePhase),
//            u64 decidedUnixMicros, u32 renderMicros, bytes. The rectangle is in pixels of the
//            frame's screen: the virtual screen itself at step 1, or the reduced screen of an
//            interactive frame, ceil(width / step) x ceil(height / step), whose pixel (x, y) stands
//            for the step x step block of virtual-screen pixels at (x * step, y * step) (clipped at
//            the edge). renderMicros: how long the sending rank had rendered the frame when it sent
//            the tile (a rank sends bands as it renders them: its last tile carries the whole
//            time). Renderers cut their segments at the Welcome's display edges (tile_codec.hpp,
//            DisplayCut), so a segment lies on the displays it touches or wholly in a bezel gap,
//            and send bezel-only segments only when the Welcome asks for them.
//   FrameEnd i32 rank, u32 tiles this rank sent for the frame, u8 flags (bit 0: the render job
//            abandoned the frame: the camera moved while it was rendered; the sink drops it as
//            superseded)
//   Control  u8 command (1 rotate, 2 zoom, 3 pan, 4 reset, 5 play, 6 pause, 7 step by a whole
//            number a, 8 seek to time step a), f64 a, f64 b (sink -> controller)
//   Bye      str reason
//   FrameNote u8 status (1 presented, 2 dropped, 3 refused, 4 superseded), str reason
//            (sink -> controller;
//            the header's frame id names the frame)
//   KeepAlive (no payload; peer -> sink, at least every kKeepAliveInterval while nothing else
//            is sent: the sink drops a greeted peer that sends nothing for its peer-idle time)
//   Playback u32 step, u32 first, u32 last, u32 stride (all < kMaxPlaybackStep, first <= step
//            <= last, stride >= 1), u8 flags (bit 0: playing), f64 rate (steps a second, 0: a step
//            a frame, 0..1e6) (controller -> sink: where a time series job is, from the header's
//            frame id on; sent when it changes)
// Sequence: peer connects, sends Hello; the sink answers Welcome, or Bye with the reason (wrong
// version, token or wall) and closes. A renderer then sends, per frame, its Tiles and a
// FrameEnd; the controller (rank 0) receives Controls and a FrameNote for every frame of its job
// that the sink presented, dropped or refused. Either side may send Bye and close.
// Jobs: every peer of one render job sends the same jobId. While a job has peers connected, the
// sink refuses peers of another job; after that, a new job id starts a new frame sequence (the
// old job's open frames are dropped and a later Hello of the old job is refused) whose frame
// window starts at the Hello's nextFrame (the frame the peer sends next).
// Version history: 1 first release; 2 adds Hello.jobId and FrameNote; 3 adds Tile.step and
// Tile.renderMicros (interactive frames, the load overlay); 4 adds the displays and the bezel flag
// to Welcome (segments cut at display edges, so the sink routes them without decoding),
// Tile.phase, FrameEnd's flags and the superseded status (abandoned frames, refinement); 5 adds
// KeepAlive (idle peers are dropped, so a silent or hung peer cannot hold the wall); 6 adds the
// time commands (play, pause, step, seek) and Playback (the wall page's time controls).
// The token travels in clear text: use an SSH tunnel or a private network between the hosts.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>
#include <voxwall/core/rect.hpp>
#include <voxwall/net/tile_codec.hpp>

namespace voxwall::net {

inline constexpr std::uint32_t kWireMagic = 0x50575756;
inline constexpr std::uint16_t kWireVersion = 6;
inline constexpr std::size_t kHeaderBytes = 32;
inline constexpr std::uint32_t kMaxPayload = 64u << 20;
inline constexpr std::size_t kMaxString = 256;
// The largest payload a peer may send before its Hello was accepted (a Hello is at most 533
// bytes): nobody can make the sink hold memory before proving who it is.
inline constexpr std::uint32_t kMaxHelloPayload = 1024;
// The coarsest interactive frame: one pixel for kMaxStep x kMaxStep virtual-screen pixels.
inline constexpr int kMaxStep = 16;
// How often a peer with nothing else to send says it is alive; a sink's peer-idle time must be
// longer (the sink's command line takes at least 10 s).
inline constexpr int kKeepAliveMs = 5000;
// The most displays a Welcome lists (a wall file allows no more).
inline constexpr std::size_t kMaxWelcomeDisplays = 1024;

enum class MessageType : std::uint16_t {
  Hello = 1,
  Welcome = 2,
  Tile = 3,
  FrameEnd = 4,
  Control = 5,
  Bye = 6,
  FrameNote = 7,
  KeepAlive = 8,
  Playback = 9,
};
enum class Role : std::uint8_t { Renderer = 1, Controller = 2 };
enum class ControlCommand : std::uint8_t {
  Rotate = 1,
  Zoom = 2,
  Pan = 3,
  Reset = 4,
  Play = 5,
  Pause = 6,
  StepBy = 7,  // a: whole steps, +-kMaxPlaybackStep
  Seek = 8,    // a: the time step, 0..kMaxPlaybackStep - 1
};
// Time steps a Playback or a time command may name (a .vwz holds at most 65536).
inline constexpr std::uint32_t kMaxPlaybackStep = 65536;
// Why a frame has its step (wire values; never reuse one).
enum class FramePhase : std::uint8_t {
  Full = 0,         // full resolution, nothing pending
  Interactive = 1,  // reduced while the camera is being steered
  Refining = 2,     // the camera settled: reduced, on the way to full resolution
};
const char* phaseName(FramePhase phase);  // "full", "interactive", "refining"
// How a frame is described in logs and on the pages: "" at step 1, "refining 1/S" for a
// refining frame, else "interactive 1/S" (a reduced frame is a steered one unless it refines).
std::string stepLabel(int step, FramePhase phase);

struct Hello {
  Role role = Role::Renderer;
  int rank = 0, rankCount = 1;
  std::string wallId, token;
  std::uint64_t jobId = 0;      // the same on every peer of one render job
  std::uint64_t nextFrame = 0;  // the frame id this peer sends (or asks about) next
};
struct Welcome {
  std::string wallId;
  int screenWidth = 0, screenHeight = 0;
  // Where renderers cut their segments: every display's rectangle (empty: none known, cut only
  // every segmentPixels); whether they also send segments no display shows.
  std::vector<voxwall::Rect> displays;
  bool bezels = true;
  // What a renderer does with this Welcome (tile_codec.hpp).
  DisplayCut cut() const { return {screenWidth, screenHeight, displays, bezels}; }
};
struct TileMessage {
  voxwall::Rect rect;  // in pixels of the frame's screen (reduced when step > 1)
  TileCodec codec = TileCodec::Jpeg;
  std::uint64_t decidedUnixMicros = 0;  // when rank 0 decided the frame's camera
  std::vector<std::byte> bytes;
  int step = 1;                    // 1: full resolution; n: an interactive frame, 1/n per side
  std::uint32_t renderMicros = 0;  // the sending rank's render time so far (last tile: all)
  FramePhase phase = FramePhase::Full;
};
// The virtual-screen rectangle that `rect` of a frame rendered at `step` stands for, clipped to
// the screenWidth x screenHeight virtual screen (empty when it lies outside).
voxwall::Rect fullScreenRect(const voxwall::Rect& rect, int step, int screenWidth,
                             int screenHeight);
// The reduced screen of an interactive frame: ceil(side / step).
inline int reducedSide(int side, int step) { return (side + step - 1) / step; }
struct FrameEnd {
  int rank = 0;
  std::uint32_t tiles = 0;
  bool abandoned = false;  // the job gave the frame up (the camera moved): drop it, superseded
};
struct Control {
  ControlCommand command = ControlCommand::Reset;
  // rotate: degrees of azimuth, elevation; zoom: factor; pan: x, y radii; step: steps; seek: step
  double a = 0, b = 0;
  bool operator==(const Control&) const = default;
};
// Where a time series job is: the step it shows, its range and whether it plays.
struct Playback {
  std::uint32_t step = 0, first = 0, last = 0, stride = 1;
  bool playing = true;
  double rate = 0;  // steps a second on the clock; 0: a step a frame
  bool operator==(const Playback&) const = default;
};
struct Bye {
  std::string reason;
};
enum class FrameStatus : std::uint8_t { Presented = 1, Dropped = 2, Refused = 3, Superseded = 4 };
struct FrameNote {
  FrameStatus status = FrameStatus::Presented;
  std::string reason;  // empty when presented
};

struct Message {
  MessageType type = MessageType::Bye;
  std::uint64_t frame = 0;
  std::vector<std::byte> payload;
};

// Whole messages (header + payload).
std::vector<std::byte> encodeMessage(const Hello& m);
std::vector<std::byte> encodeMessage(const Welcome& m);
std::vector<std::byte> encodeMessage(std::uint64_t frame, const TileMessage& m);
std::vector<std::byte> encodeMessage(std::uint64_t frame, const FrameEnd& m);
std::vector<std::byte> encodeMessage(const Control& m);
std::vector<std::byte> encodeMessage(const Bye& m);
std::vector<std::byte> encodeMessage(std::uint64_t frame, const FrameNote& m);
std::vector<std::byte> encodeKeepAlive();
std::vector<std::byte> encodeMessage(std::uint64_t frame, const Playback& m);

// Header check: magic, version, type, flags, length limit, header checksum. Returns the payload
// length. Throws FormatError(source, ...) naming what is wrong (a version mismatch says both).
std::uint32_t checkHeader(std::span<const std::byte, kHeaderBytes> header,
                          const std::string& source, MessageType* type, std::uint64_t* frame);
// Payload check against the header's checksum. Throws FormatError. (Fuzzing builds skip both
// checksums, so the fuzzer reaches the decoders behind them.)
void checkPayload(std::span<const std::byte, kHeaderBytes> header,
                  std::span<const std::byte> payload, const std::string& source);

// Payload decoders: every length is checked, trailing bytes are an error. Throw FormatError.
Hello decodeHello(std::span<const std::byte> payload, const std::string& source);
Welcome decodeWelcome(std::span<const std::byte> payload, const std::string& source);
TileMessage decodeTileMessage(std::span<const std::byte> payload, const std::string& source);
FrameEnd decodeFrameEnd(std::span<const std::byte> payload, const std::string& source);
Control decodeControl(std::span<const std::byte> payload, const std::string& source);
// Why a command's numbers are out of its bounds ("zoom takes a factor from 0.001 to 1000"); empty
// when they are within them.
std::string controlProblem(const Control& m);
Bye decodeBye(std::span<const std::byte> payload, const std::string& source);
FrameNote decodeFrameNote(std::span<const std::byte> payload, const std::string& source);
Playback decodePlayback(std::span<const std::byte> payload, const std::string& source);
// One line for a FrameNote: "frame 12 dropped: too many frames open".
std::string describe(std::uint64_t frame, const FrameNote& note);

// Splits a byte stream into messages: feed() what arrived, next() returns whole messages.
// Throws FormatError on the first bad header or payload (the stream is then unusable).
class MessageReader {
 public:
  explicit MessageReader(std::string source) : source_(std::move(source)) {}
  void feed(std::span<const std::byte> bytes);
  std::optional<Message> next();
  std::size_t buffered() const { return buffer_.size() - start_; }

 private:
  std::string source_;
  std::vector<std::byte> buffer_;
  std::size_t start_ = 0;
};

}  // namespace voxwall::net
