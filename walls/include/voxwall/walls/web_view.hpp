// The wall in a browser: `voxwall sink --http HOST:PORT` serves one page (embedded in the binary)
// and a WebSocket that pushes the presented frames, scaled down, with what the load balancer did
// (which rank rendered which rectangle, and how long it took) and the sink's numbers; the page
// sends camera commands back, which travel the same Control path as commands typed on stdin.
//
// HTTP (Boost.Beast, on its own thread and io_context: tile intake never waits for a viewer):
//   GET /          the page (text/html); GET /ws  the WebSocket; anything else 404 (no request is
//   ever mapped to a file), other methods 405. Requests: headers at most 8 KiB, no body, read
//   within 10 s (slow clients are cut off).
// WebSocket (text, JSON from the sink; text commands from the page, at most kMaxViewerMessage
// bytes each):
//   sink -> page  {"type":"wall", "id", "width", "height", "displays":[{"name","x","y","w","h"}],
//                  "token": whether one is required}                          (on connect)
//                 {"type":"auth", "ok": true}                     (after a right token)
//                 {"type":"error", "message"}                     (a command that was not taken)
//                 binary: u32 n (little-endian), n bytes of JSON {"type":"frame", "frame",
//                  "step", "width", "height" (of the JPEG), "tiles":[{"rank","x","y","w","h"}]
//                  (what each rank rendered, in virtual-screen pixels: its tiles' segments
//                  joined), "ranks":{"R": render ms}, "latency_ms", "bytes", "presented" (the
//                  sink's count so far), "dropped" (skipped or dropped so far),
//                  "ranks_connected"}, then the JPEG.
//   page -> sink  "auth TOKEN" | "rotate DAZ DEL" | "zoom FACTOR" | "pan DX DY" | "reset"
// Security: with a token, a viewer gets no frame and no command is taken before "auth" with the
// right one (a wrong one closes the connection). A WebSocket whose Origin is not this server's
// own (http://<the Host it was asked as>) or one of `origins` is refused (403): another site's
// page in the operator's browser cannot steer the wall. Served on loopback, a request whose Host
// is not a loopback name (or the host of one of `origins`) is refused too (403; DNS rebinding).
// At most 256 HTTP requests are read or answered at once. Anything else (binary from the page, an
// unknown or malformed command, a message over the limit) closes the connection. Commands are
// rate-limited per viewer. A viewer that does not keep up gets the newest frame when it is ready
// (frames in between are dropped for it; the page counts them from "presented"); one that stops
// reading holds one frame of memory, not more, and is closed by the WebSocket's idle timeout.
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
  int maxViewers = 64;               // WebSocket viewers at once; more are refused
  int maxWidth = 1920;               // frames are scaled down by whole factors to fit
  int jpegQuality = 80;
  double commandsPerSecond = 60;  // per viewer (a burst of twice that is allowed)
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
  // Binds and listens (throws net::NetError when it cannot); serves once start() was called.
  // `control` gets every command a viewer sent (on the web thread).
  WebView(const Wall& wall, WebViewSettings settings, Control control, SinkLog log = {});
  ~WebView();
  std::uint16_t port() const;
  void start();
  // Closes every connection and ends the web thread.
  void stop();
  // The newest presented frame; returns at once (the web thread scales and encodes it, and only
  // when someone watches). Thread-safe.
  void present(ViewerFrame frame);

  struct Impl;  // web_view.cpp's (its connections reach it)

 private:
  std::unique_ptr<Impl> impl_;
};

// The page the server sends (HTML with its script and style inside).
const std::string& webPage();

}  // namespace voxwall::walls
