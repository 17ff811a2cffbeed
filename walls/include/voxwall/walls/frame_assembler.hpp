// Frame assembly without sockets: the tiles (JPEG segments) of a render job's frames go in,
// complete frames come out as the segments the ranks sent, still encoded: the sink routes them
// to the displays' pages and decodes pixels only for what needs pixels (frame_pixels.hpp). A
// frame is complete when every display pixel has arrived (every virtual-screen pixel when the
// sink writes the whole screen); it is never shown torn. A segment is accepted after a cheap
// check of its header against its rectangle (net::checkTile). Every frame the assembler drops or
// refuses is reported once, with why.
//
// Bounds (a peer past its Hello is trusted with the wall, not with the sink's memory):
//   - frame ids: a sequence starts at a first frame (the job's, from its Hello); before any
//     frame completed, only ids in [first, first + window] open a frame, after that only ids in
//     (last complete, last complete + window]. A bogus id (2^64 - 1) is refused and cannot
//     wedge the wall.
//   - memory: tiles are kept as they arrived (encoded), plus one coverage bit per virtual-screen
//     pixel per open frame; the bytes held for open frames stay under `pendingBytes` (the oldest
//     open frames are dropped to make room), and at most `pendingFrames` frames are open.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/net/wire.hpp>
#include <voxwall/walls/wall.hpp>

namespace voxwall::walls {

inline constexpr std::uint64_t kDefaultFrameWindow = 1 << 16;

// One segment of a frame as a rank sent it, still encoded.
struct Segment {
  voxwall::Rect rect;    // pixels of the frame's screen, as sent (the reduced screen at step > 1)
  voxwall::Rect screen;  // the virtual-screen pixels it stands for (clipped to the screen)
  net::TileCodec codec = net::TileCodec::Jpeg;
  std::shared_ptr<const std::vector<std::byte>> bytes;  // shared with whoever forwards them
  int rank = 0;
};

struct AssembledFrame {
  std::uint64_t frame = 0;
  std::vector<Segment> segments;        // in arrival order (a later one wins where they overlap)
  std::uint64_t decidedUnixMicros = 0;  // earliest camera decision of its tiles (rank 0's clock)
  std::uint64_t bytes = 0;              // encoded tile bytes received
  int tiles = 0;
  // 1: full resolution; n > 1: an interactive frame rendered at 1/n per side and upsampled here
  // (every virtual-screen pixel repeats the reduced pixel whose block it lies in).
  int step = 1;
  net::FramePhase phase = net::FramePhase::Full;  // why it has that step
  // Every rank that sent tiles of the frame, with its render time for the frame.
  std::map<int, std::uint32_t> rankRenderMicros;
};

struct FrameEvent {
  std::uint64_t frame = 0;
  net::FrameNote note;  // Dropped or Refused, with the reason
};

struct AssemblerLimits {
  int pendingFrames = 16;          // open frames at once; the oldest is dropped
  std::uint64_t pendingBytes = 0;  // bytes held for open frames; 0: defaultPendingBytes(wall)
  std::uint64_t frameWindow = kDefaultFrameWindow;
  // Every virtual-screen pixel must arrive, bezels too (the sink writes the whole screen and
  // asks the ranks for bezel segments); otherwise only the displays' pixels.
  bool wholeScreen = false;
};

// Room for two frames of raw pixels plus 64 MiB (tiles are held encoded: far less in practice).
std::uint64_t defaultPendingBytes(const Wall& wall);

class FrameAssembler {
 public:
  using Events = std::function<void(const FrameEvent&)>;
  // Throws std::invalid_argument when pendingBytes cannot hold one whole frame.
  FrameAssembler(const Wall& wall, AssemblerLimits limits, Events events);

  // Starts a new frame sequence (a new render job) at `firstFrame`: open frames are dropped with
  // `why`, and frame ids are judged afresh.
  void startSequence(std::uint64_t firstFrame, const std::string& why);
  // Adds one tile of `frame` (its bytes are taken); returns the frame when this tile completed
  // it. Throws FormatError(peer, ...) for a tile outside the screen (the reduced screen of its
  // step), one whose step differs from the frame's other tiles, or one whose header disagrees
  // with its rectangle (no pixel is marked then). Tiles of refused or already settled frames
  // are ignored (reported once).
  std::optional<AssembledFrame> addTile(std::uint64_t frame, net::TileMessage tile, int rank,
                                        const std::string& peer);
  // The render job abandoned `frame` (the camera moved while it was rendered): it is dropped as
  // superseded and its later tiles are ignored, if it is open or among the `pendingFrames`
  // frames after the last complete one (in flight with no tile sent yet: its ranks may all give
  // it up before sending any). Frames already settled, further ahead or outside the frame window
  // are left alone (a FrameEnd cannot settle frames the job has not begun). Whether it was
  // superseded.
  bool supersede(std::uint64_t frame, const std::string& why);

  std::uint64_t heldBytes() const { return heldBytes_; }
  std::size_t openFrames() const { return open_.size(); }
  std::uint64_t pendingBytesLimit() const { return limits_.pendingBytes; }

 private:
  struct Open {
    std::vector<std::uint64_t> covered;  // bitmap over the virtual screen
    long long coveredPixels = 0;         // of the pixels that must arrive
    std::uint64_t heldBytes = 0;
    std::uint64_t sentPixels = 0;  // the tiles' areas as sent (overlaps counted each time)
    AssembledFrame info;
  };
  // What holding a tile costs: its bytes once per display it is forwarded to (at least once).
  std::uint64_t tileCost(const net::TileMessage& tile, const voxwall::Rect& screen) const;
  // Throws FormatError when `tile` would make the frame's tiles cover its screen (at the tile's
  // step) more than twice over: no honest job overlaps its segments.
  void checkOverlap(std::uint64_t frame, const net::TileMessage& tile, std::uint64_t sentBefore,
                    const std::string& peer) const;
  // Marks `r` (virtual-screen pixels) as arrived in `f`.
  void cover(Open& f, const voxwall::Rect& r) const;
  void drop(std::uint64_t frame, const std::string& why);
  void report(std::uint64_t frame, net::FrameStatus status, const std::string& why);
  bool reported(std::uint64_t frame) const { return reported_.count(frame) > 0; }
  std::optional<std::string> outsideWindow(std::uint64_t frame) const;
  // The full-screen rectangle of a tile's rectangle at its step; throws FormatError for a step or
  // rectangle off the screen.
  voxwall::Rect screenRect(const net::TileMessage& tile, const std::string& peer) const;
  // Drops the oldest other frames until `need` more bytes fit; false when `frame` alone holds too
  // much (it is dropped too).
  bool makeRoom(std::uint64_t frame, std::uint64_t need);
  // The open frame `frame`, opened at this step and phase if it was not.
  Open& openFrame(std::uint64_t frame, const net::TileMessage& tile);
  // `frame` has every pixel: the frames before it are dropped, it is reported and handed out.
  AssembledFrame complete(std::uint64_t frame);

  const Wall& wall_;
  AssemblerLimits limits_;
  Events events_;
  std::vector<std::uint64_t> needed_;  // bitmap: the pixels that must arrive (displays, or all)
  long long neededPixels_ = 0;
  std::uint64_t coverageBytes_ = 0;  // one open frame's coverage bitmap
  std::map<std::uint64_t, Open> open_;
  std::uint64_t firstFrame_ = 0;
  std::optional<std::uint64_t> lastComplete_;
  std::set<std::uint64_t> reported_;  // frames whose fate was reported (bounded, newest kept)
  std::uint64_t heldBytes_ = 0;
};

}  // namespace voxwall::walls
