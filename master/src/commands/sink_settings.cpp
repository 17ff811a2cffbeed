#include "sink_settings.hpp"

#include <voxwall/core/text.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/wall.hpp>

#include "option_checks.hpp"

namespace voxwall::cli {

namespace {

// The wall, where the sink listens, and the frames it writes.
void addWallOptions(CLI::App& cmd, SinkOptions& o) {
  cmd.add_option("--wall", o.wall, "Wall file (walls/*.json, or a Tide configuration)")->required();
  cmd.add_option("--surface", o.surface,
                 "Which surface of a Tide configuration with several to show (0: the first; "
                 "the sink lists them when it starts)")
      ->capture_default_str();
  cmd.add_option("--listen", o.listen,
                 "Address and port to listen on (loopback by default; 0.0.0.0:PORT for all)")
      ->capture_default_str();
  cmd.add_option("--out", o.out,
                 "Write every presented frame as DIR/frame_NNNNN_<display>.png (or .jpg), on a "
                 "thread of its own: a writer that falls behind skips frames, never the wall");
  cmd.add_option("--out-format", o.outFormat,
                 "The displays' files: png (lossless, zlib level 1) or jpg (quality 95, several "
                 "times faster)")
      ->capture_default_str();
  cmd.add_option("--write-queue", o.writeQueue,
                 "Presented frames waiting to be written; when it is full the oldest is skipped")
      ->capture_default_str();
  cmd.add_flag("--mosaic", o.mosaic,
               "Also write the whole virtual screen, bezels included (the ranks then send the "
               "bezels' pixels too, and a frame is complete when the whole screen arrived)");
  cmd.add_flag("--no-stdin", o.noStdin, "Do not read camera commands from stdin");
  cmd.add_flag("-q,--quiet", o.quiet, "Print nothing but errors");
}

// Who may connect, and what the sink holds for them.
void addPeerOptions(CLI::App& cmd, SinkOptions& o) {
  cmd.add_option("--token", o.token,
                 "Refuse peers and pages that do not present this token (it travels in clear "
                 "text: tunnel the ports through SSH or keep them on a private network)");
  cmd.add_option("--frames", o.frames,
                 "Exit after this many frames were presented or dropped (incomplete), once the "
                 "presented ones are written; 0: run until interrupted")
      ->capture_default_str();
  cmd.add_option("--pending", o.pending,
                 "Incomplete frames held at once before the oldest is dropped")
      ->capture_default_str();
  cmd.add_option("--pending-mib", o.pendingMiB,
                 "Memory for tiles of incomplete frames; when it is full the oldest frame is "
                 "dropped (default 0: room for two frames of raw pixels of this wall plus 64 MiB)")
      ->capture_default_str();
  cmd.add_option("--max-peers", o.maxPeers,
                 "Connections at once (ranks, rank 0's control, not yet greeted); more are "
                 "refused")
      ->capture_default_str();
  cmd.add_option("--hello-timeout-ms", o.helloTimeoutMs,
                 "Drop a peer that has not said Hello by then")
      ->capture_default_str();
  cmd.add_option("--peer-idle", o.peerIdle,
                 "Seconds (at least 10) after which a peer that has sent nothing is dropped: "
                 "ranks and rank 0 send a keep-alive every 5 s while they have nothing else to "
                 "send, so a silent peer (a squatter, a hung rank) cannot hold the wall for its "
                 "job; once its job has no peer left, another job may take the wall")
      ->capture_default_str();
  cmd.add_option("--job-idle", o.jobIdle,
                 "Seconds (10 to 86400) after which a running job that has presented no frame "
                 "(since it started or its last one) gives the wall up to another job that asks "
                 "for it: longer than the longest honest frame (frames of 35 s were measured on "
                 "a 2-core VM; a first frame also loads the volume)")
      ->capture_default_str();
}

// The wall's web pages and the display pages' swap barrier.
void addPageOptions(CLI::App& cmd, SinkOptions& o) {
  cmd.add_option("--http", o.http,
                 "Serve the wall's pages at HOST:PORT (e.g. 127.0.0.1:8080): / the overview (the "
                 "live wall, the load balancer's rectangles, camera control by mouse and touch), "
                 "/display/<name> one display at native resolution for a kiosk browser, "
                 "/displays the list with launch lines. Loopback is the safe choice: reach it "
                 "through an SSH tunnel (ssh -L 8080:127.0.0.1:8080 wallhost). With --token the "
                 "pages ask for it");
  cmd.add_option("--http-origin", o.httpOrigins,
                 "Another Origin whose pages may use the pages' WebSockets (e.g. "
                 "http://localhost:8080 when tunnelled under another name); repeatable");
  cmd.add_option("--max-viewers", o.maxViewers,
                 "Overview pages at once; when all are held, a viewer takes the place of the "
                 "oldest viewer of an address holding at least two more than its own, else it is "
                 "refused")
      ->capture_default_str();
  cmd.add_option("--max-display-pages", o.maxDisplayPages,
                 "Display pages at once (0: two per display, plus 8); when all are held, a page "
                 "takes the place of the oldest page of a display (else of an address on its own "
                 "display) holding at least two more than its own, else it is refused")
      ->capture_default_str();
  cmd.add_option("--swap-timeout", o.swapTimeoutMs,
                 "Milliseconds a display page may take to be ready for a frame before it leaves "
                 "the swap barrier (it rejoins when it keeps up); the wall never waits longer. A "
                 "page ready later than both twice the frame interval and three times the other "
                 "pages' median, 3 rounds in a row, leaves too")
      ->capture_default_str();
  cmd.add_option("--swap-lead", o.swapLeadMs,
                 "Display pages are told to show a frame this many milliseconds ahead, on the "
                 "display refresh nearest that moment, so that they switch on the same refresh "
                 "(display hosts' clocks must agree, e.g. through NTP; a page whose clock is off "
                 "by over a second shows at once)")
      ->capture_default_str();
}

}  // namespace

void addSinkOptions(CLI::App& cmd, SinkOptions& o) {
  addWallOptions(cmd, o);
  addPeerOptions(cmd, o);
  addPageOptions(cmd, o);
}

walls::SinkSettings sinkSettings(const SinkOptions& o) {
  walls::SinkSettings s;
  s.wall = walls::selectSurface(walls::loadWalls(o.wall), o.surface, o.wall);
  std::tie(s.listenHost, s.listenPort) = net::parseEndpoint(o.listen, "--listen");
  s.outDir = o.out;
  s.outFormat = choose<walls::FrameFormat>(o.outFormat, "--out-format",
                                           {{"png", walls::FrameFormat::Png},
                                            {"jpg", walls::FrameFormat::Jpeg},
                                            {"jpeg", walls::FrameFormat::Jpeg}});
  s.writeQueue = inRange(o.writeQueue, 1, 1024, "--write-queue");
  s.mosaic = o.mosaic;
  s.token = o.token;
  s.maxFrames = inRange(o.frames, 0, 1 << 30, "--frames");
  s.pendingFrames = inRange(o.pending, 1, 64, "--pending");
  s.maxPeers = inRange(o.maxPeers, 1, 65536, "--max-peers");
  s.helloTimeoutMs = inRange(o.helloTimeoutMs, 1, 600000, "--hello-timeout-ms");
  if (!(o.peerIdle >= 10 && o.peerIdle <= 86400))
    throw std::invalid_argument("--peer-idle " + formatLine("%g", o.peerIdle) +
                                ": expected 10 to 86400 seconds (ranks send a keep-alive every "
                                "5 s)");
  s.peerIdleMs = int(o.peerIdle * 1000);
  if (!(o.jobIdle >= 10 && o.jobIdle <= 86400))
    throw std::invalid_argument("--job-idle " + formatLine("%g", o.jobIdle) +
                                ": expected 10 to 86400 seconds");
  s.jobIdleMs = int(o.jobIdle * 1000);
  if (o.pendingMiB > (1u << 20)) throw std::invalid_argument("--pending-mib is over 1 TiB");
  s.pendingBytes = o.pendingMiB << 20;
  if (!o.http.empty()) {
    std::tie(s.httpHost, s.httpPort) = net::parseEndpoint(o.http, "--http");
    for (const auto& origin : o.httpOrigins)
      if (origin.rfind("http://", 0) != 0 && origin.rfind("https://", 0) != 0)
        throw std::invalid_argument("--http-origin '" + origin +
                                    "': expected http://HOST[:PORT] or https://HOST[:PORT]");
    s.httpOrigins = o.httpOrigins;
  } else if (!o.httpOrigins.empty()) {
    throw std::invalid_argument("--http-origin goes with --http");
  }
  s.maxViewers = inRange(o.maxViewers, 1, 4096, "--max-viewers");
  s.maxDisplayPages = inRange(o.maxDisplayPages, 0, 4096, "--max-display-pages");
  s.swapTimeoutMs = inRange(o.swapTimeoutMs, 1, 60000, "--swap-timeout");
  s.swapLeadMs = inRange(o.swapLeadMs, 0, 1000, "--swap-lead");
  return s;
}

}  // namespace voxwall::cli
