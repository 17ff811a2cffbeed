// The wall in browsers: `voxwall sink --http HOST:PORT` serves the overview page (the whole wall
// scaled down, the load balancer's rectangles, camera control) and one page per display of the
// wall, which a kiosk browser on that display's host opens full screen: that display's pixels at
// native resolution, switching frames together with every other display (swap_barrier.hpp).
//
// HTTP (Boost.Beast, on its own thread and io_context: tile intake never waits for a viewer):
//   GET /                  the overview page (text/html)
//   GET /display/<name>    the page of one display (404 for a name the wall does not have)
//   GET /displays          the displays, each with a launch line for a kiosk browser (text/html)
//   GET /displays.json     the same as JSON
//   GET /ws                the overview's WebSocket; GET /ws/display/<name> a display page's
//   Anything else 404 (no request is ever mapped to a file), other methods 405. Requests: headers
//   at most 8 KiB, no body, read within 10 s (slow clients are cut off).
// Overview WebSocket (text JSON from the sink; text commands from the page, at most
// kMaxViewerMessage bytes each):
//   sink -> page  {"type":"login"} (on connect when a token is required: nothing about the wall
//                  is sent before it)
//                 {"type":"auth", "ok": true}                     (after a right token)
//                 {"type":"wall", "id", "width", "height", "displays":[{"name","x","y","w","h"}],
//                  "token": whether one is required}         (on connect, or after the token)
//                 {"type":"error", "message"}                     (a command that was not taken)
//                 binary: u32 n (little-endian), n bytes of JSON {"type":"frame", "frame",
//                  "step", "phase" ("full", "interactive" or "refining"), "width", "height" (of
//                  the JPEG), "tiles":[{"rank","x","y","w","h"}]
//                  (what each rank rendered, in virtual-screen pixels: its tiles' segments
//                  joined), "ranks":{"R": render ms}, "latency_ms", "bytes", "presented" (the
//                  sink's count so far), "dropped" (dropped so far), "ranks_connected"}, then the
//                  JPEG (the frame decoded at 1/k, k the smallest whole factor that fits
//                  maxWidth, on a thread of its own, only while someone watches).
//   page -> sink  "auth TOKEN" | "rotate DAZ DEL" | "zoom FACTOR" | "pan DX DY" | "reset" |
//                 "next" (it took its frame: the sink sends the next one, the newest, only then)
// Display page WebSocket:
//   sink -> page  {"type":"login"} (on connect when a token is required)
//                 {"type":"auth", "ok": true}
//                 {"type":"display", "name", "wall", "x", "y", "w", "h" (its rectangle on the
//                  virtual screen), "token", "swap_timeout_ms", "background":"#rrggbb"}
//                  (on connect, or after the token)
//                 binary: u32 n, n bytes of JSON {"type":"frame", "frame", "seq" (the sink's
//                  count of presented frames: frame ids restart with each job), "step", "phase",
//                  "latency_ms", "segments":[{"x","y","w","h" (pixels of the frame's screen,
//                  reduced at step > 1), "codec":"jpeg"|"raw"|"deflate", "bytes"}]}, then each
//                  segment's bytes as the rank sent them, in that order: every segment that
//                  touches the display
//                 {"type":"show", "seq", "at"}  show that frame on the display refresh nearest
//                  "at" (Unix milliseconds on the sink's clock, which pages on other hosts share
//                  through NTP; a page whose clock is over a second off shows it at once)
//   page -> sink  "auth TOKEN" | "ready SEQ" (decoded, can show it) | "shown SEQ UNIXMS" (when it
//                  showed it: milliseconds since 1970 with a fraction, the page's clock)
// The sink reports the spread of the "shown" times of every frame the pages switched to together.
// Security: with a token, a viewer or page gets nothing and no command is taken before "auth"
// with the right one (a wrong one closes the connection). A WebSocket whose Origin is not this
// server's own (http://<the Host it was asked as>) or one of `origins` is refused (403): another
// site's page in the operator's browser cannot steer the wall. Served on loopback, a request
// whose Host is not a loopback name (or the host of one of `origins`) is refused too (403; DNS
// rebinding). At most 256 HTTP requests are read or answered at once. Anything else (binary from
// a page, an unknown or malformed message, one over the limit) closes the connection. Messages
// are rate-limited per connection. An overview viewer that does not keep up gets the newest frame
// when it is ready (frames in between are dropped for it); a display page has one frame in flight
// (swap_barrier.hpp). A connection that stops reading holds one frame of memory, not more, and
// is closed by the WebSocket's idle timeout.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/net/wire.hpp>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/sink.hpp>
#include <voxwall/walls/wall.hpp>

namespace voxwall::walls {

inline constexpr std::size_t kMaxViewerMessage = 1024;

struct WebViewSettings {
  std::string host = "127.0.0.1";    // loopback unless told otherwise
  std::uint16_t port = 0;            // 0: any free port (see WebView::port)
  std::string token;                 // empty: none
  std::vector<std::string> origins;  // other allowed Origins, e.g. "http://localhost:8080"
  int maxViewers = 64;               // overview WebSockets at once; more are refused
  int maxDisplayPages = 0;           // display pages at once; 0: 2 per display, plus 8
  int swapTimeoutMs = 500;           // a display page not ready by then leaves the barrier
  // Pages are told to show a frame at "now + swapLeadMs" (Unix time): every page draws it on the
  // display refresh nearest that moment, whatever moment the message reached it.
  int swapLeadMs = 25;
  int maxWidth = 1920;  // overview frames are scaled down by whole factors to fit
  int jpegQuality = 80;
  double commandsPerSecond = 60;       // per viewer (a burst of twice that is allowed)
  double pageMessagesPerSecond = 600;  // per display page (two a frame; a burst of twice that)
  // With a token, a WebSocket that has not sent it by then is closed (until then it holds no
  // viewer's place; at most 4 such per address).
  int authTimeoutMs = 5000;
  // A viewer or page whose last write has not gone out by then reads nothing: it is cut off,
  // whatever it sends.
  int writeTimeoutMs = 10000;
};

// One presented frame as the viewers see it: the assembler's frame (handed over, not copied),
// what it took to present it and the sink's numbers then.
struct ViewerFrame {
  std::shared_ptr<const AssembledFrame> frame;
  double latencyMs = 0;
  SinkStats stats;
};

class WebView {
 public:
  using Control = std::function<void(const net::Control&)>;
  // The displays' pages as the swap barrier sees them, after every change (on the web thread).
  struct SwapStats {
    int pages = 0, inBarrier = 0, framesSwapped = 0;
    double lastSpreadMs = 0;  // of the last frame every page that showed it reported
  };
  using SwapReport = std::function<void(const SwapStats&)>;
  // Binds and listens (throws net::NetError when it cannot); serves once start() was called.
  // `control` gets every command a viewer sent (on the web thread).
  WebView(const Wall& wall, WebViewSettings settings, Control control, SinkLog log = {},
          SwapReport swapReport = {});
  ~WebView();
  std::uint16_t port() const;
  void start();
  // Closes every connection and ends the web thread.
  void stop();
  // A presented frame; returns at once. Its segments go to the displays' pages (web thread); the
  // overview's picture is decoded and encoded on a thread of its own, only while someone watches,
  // newest first. Thread-safe.
  void present(ViewerFrame frame);

  struct Impl;  // web_view.cpp's (its connections reach it)

 private:
  std::unique_ptr<Impl> impl_;
};

// The pages the server sends (HTML with their script and style inside): the overview and the
// display page.
const std::string& webPage();
const std::string& displayPage();

}  // namespace voxwall::walls
