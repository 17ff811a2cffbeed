// The data sink of a display wall: accepts the rendering ranks and rank 0's control connection
// (net/wire.hpp), collects the segments of each frame and presents a frame only when every pixel
// of every display has arrived (never a torn or partial frame). It is a router, not a decoder:
// a presented frame's segments go as they arrived to the displays' pages (web_view.hpp, which
// switch frames together through a swap barrier); pixels are decoded only for files and the
// overview page. It drops and reports frames it cannot complete, survives peers that join late,
// drop, or send garbage, writes per-display images off the presentation path (and optionally a
// mosaic, all or nothing: frame_files.hpp; a writer that falls behind skips frames, never the
// wall) and forwards camera and time commands to rank 0.
// Hostile peers: the protocol logic (sink_core.hpp) bounds what any peer can make it hold;
// here, connections are capped (maxPeers), peers without a Hello are dropped after
// helloTimeoutMs, greeted peers silent for peerIdleMs are dropped (so a squatter or a hung rank
// cannot hold the wall for its job), and running out of file descriptors pauses accepting
// instead of ending it.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/net/wire.hpp>
#include <voxwall/walls/frame_files.hpp>
#include <voxwall/walls/wall.hpp>

namespace voxwall::walls {

struct SinkSettings {
  Wall wall;
  std::string listenHost = "127.0.0.1";  // loopback unless told otherwise
  std::uint16_t listenPort = 0;          // 0: any free port (see Sink::port)
  std::string token;                     // empty: no token required
  std::string outDir;                    // empty: frames are assembled and counted, not written
  bool mosaic = false;  // also write the whole virtual screen (the ranks then send bezels too)
  FrameFormat outFormat = FrameFormat::Png;  // the displays' files
  int writeQueue = 8;  // presented frames waiting to be written; beyond, the oldest is skipped
  int maxFrames = 0;   // stop after this many frames were presented, dropped or superseded
  // Incomplete frames held at once; the oldest is dropped. Ranks a few frames apart in the
  // kernel's socket buffers are normal at full speed (a bigeye frame is about 1 MB of JPEG).
  int pendingFrames = 16;
  std::uint64_t pendingBytes = 0;       // bytes held for incomplete frames; 0: 2 frames + 64 MiB
  std::uint64_t frameWindow = 1 << 16;  // frame ids accepted past the last complete one
  int maxPeers = 256;                   // connections at once; more are refused
  int helloTimeoutMs = 5000;            // a peer that sends no Hello by then is dropped
  int peerIdleMs = 30000;               // a greeted peer silent this long is dropped
  // A running job that has presented no frame this long (since it started or its last one)
  // gives the wall up to another job that asks for it: a squatter sending keep-alives, a job
  // that never completes a frame, a rank left over after its job ended.
  int jobIdleMs = 300000;
  int viewerAuthTimeoutMs = 5000;    // WebViewSettings::authTimeoutMs
  int viewerWriteTimeoutMs = 10000;  // WebViewSettings::writeTimeoutMs
  // The browser view (web_view.hpp): empty httpHost: none. The token above guards it too.
  std::string httpHost;
  std::uint16_t httpPort = 0;            // 0: any free port (see Sink::httpPort)
  std::vector<std::string> httpOrigins;  // other Origins whose pages may watch and steer
  int maxViewers = 64;                   // overview pages at once
  int maxDisplayPages = 0;               // display pages at once; 0: 2 per display, plus 8
  int swapTimeoutMs = 500;               // a display page not ready by then leaves the swap barrier
  int swapLeadMs = 25;                   // pages show a frame on the refresh nearest "now + this"
};

struct SinkStats {
  int framesPresented = 0, framesDropped = 0, framesRefused = 0;
  int framesSuperseded = 0;  // abandoned by the render job: the camera moved while they rendered
  int framesNotWritten = 0;  // presented, but skipped by the file writer (it fell behind)
  int framesWritten = 0;
  int peersAccepted = 0, peersRefused = 0, peersDropped = 0;
  bool controllerConnected = false;  // rank 0's control connection is up
  int renderersConnected = 0;        // rendering ranks greeted and connected now
  std::uint64_t bytesReceived = 0;
  double meanLatencyMs = 0;  // camera decided on rank 0 -> frame presented (same clock: one host)
  // The displays' pages (web_view.hpp): connected, in the swap barrier, frames they switched to
  // together, and the spread of the times they showed the last such frame.
  int displayPages = 0, displayPagesInBarrier = 0;
  int framesSwapped = 0;
  double lastSwapSpreadMs = 0;
  // Where the current job's time series is (the controller's last Playback); none for a job of
  // one volume.
  std::optional<net::Playback> playback;
};

// One line per event (frame presented or dropped, peer refused or dropped).
using SinkLog = std::function<void(const std::string&)>;

class Sink {
 public:
  // Binds the listening socket and, with an output folder, removes what a killed sink left
  // there (frame_files.hpp). Throws net::NetError when it cannot listen, FormatError for the
  // folder, std::invalid_argument for settings that cannot work.
  explicit Sink(SinkSettings settings, SinkLog log = {});
  ~Sink();
  std::uint16_t port() const;
  // The browser view's port (0 without one).
  std::uint16_t httpPort() const;
  // Serves until maxFrames frames were settled (and the frames waiting to be written are
  // written) or stop() was called. Thread: any one thread. Throws FormatError when a frame cannot
  // be written (full disk): the sink stops then, since every later frame would be lost too.
  void run();
  // Thread-safe.
  void stop();
  // Forwards a camera command to the controller (rank 0), if one is connected. Thread-safe.
  void sendControl(const net::Control& control);
  SinkStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Parses a control line typed at the sink (or sent by a page): "rotate DAZ DEL", "zoom FACTOR",
// "pan DX DY", "reset", and for a time series "play", "pause", "step N" (N whole, may be
// negative), "seek STEP". Throws std::invalid_argument with a usage line.
net::Control parseControlLine(const std::string& line);

}  // namespace voxwall::walls
