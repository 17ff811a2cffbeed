#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>
#include <thread>
#include <vector>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/sink.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"

namespace voxwall::cli {
namespace {

struct SinkOptions {
  std::string wall, listen = "127.0.0.1:7400", out, token, http;
  std::vector<std::string> httpOrigins;
  int surface = 0, frames = 0, pending = 4, maxPeers = 256, helloTimeoutMs = 5000;
  int maxViewers = 64;
  std::uint64_t pendingMiB = 0;
  bool mosaic = false, quiet = false, noStdin = false;
};

void runSink(const SinkOptions& o) {
  walls::SinkSettings settings;
  const auto surfaces = walls::loadWalls(o.wall);
  settings.wall = walls::selectSurface(surfaces, o.surface, o.wall);
  std::tie(settings.listenHost, settings.listenPort) = net::parseEndpoint(o.listen, "--listen");
  settings.outDir = o.out;
  settings.mosaic = o.mosaic;
  settings.token = o.token;
  if (o.frames < 0) throw std::invalid_argument("--frames must not be negative");
  settings.maxFrames = o.frames;
  if (o.pending < 1 || o.pending > 64) throw std::invalid_argument("--pending must be in [1, 64]");
  settings.pendingFrames = o.pending;
  if (o.maxPeers < 1 || o.maxPeers > 65536)
    throw std::invalid_argument("--max-peers must be in [1, 65536]");
  settings.maxPeers = o.maxPeers;
  if (o.helloTimeoutMs < 1 || o.helloTimeoutMs > 600000)
    throw std::invalid_argument("--hello-timeout-ms must be in [1, 600000]");
  settings.helloTimeoutMs = o.helloTimeoutMs;
  if (o.pendingMiB > (1u << 20)) throw std::invalid_argument("--pending-mib is over 1 TiB");
  settings.pendingBytes = o.pendingMiB << 20;
  if (!o.http.empty()) {
    std::tie(settings.httpHost, settings.httpPort) = net::parseEndpoint(o.http, "--http");
    for (const auto& origin : o.httpOrigins)
      if (origin.rfind("http://", 0) != 0 && origin.rfind("https://", 0) != 0)
        throw std::invalid_argument("--http-origin '" + origin +
                                    "': expected http://HOST[:PORT] or https://HOST[:PORT]");
    settings.httpOrigins = o.httpOrigins;
  } else if (!o.httpOrigins.empty()) {
    throw std::invalid_argument("--http-origin goes with --http");
  }
  if (o.maxViewers < 1 || o.maxViewers > 4096)
    throw std::invalid_argument("--max-viewers must be in [1, 4096]");
  settings.maxViewers = o.maxViewers;

  // SIGINT and SIGTERM end the sink cleanly (the frame being written is finished).
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  const bool quiet = o.quiet;
  // Shared with the detached threads below, which may outlive this function until exit.
  const auto sinkPtr = std::make_shared<walls::Sink>(settings, [quiet](const std::string& line) {
    if (quiet) return;
    std::printf("%s\n", line.c_str());
    std::fflush(stdout);
  });
  walls::Sink& sink = *sinkPtr;
  const auto& wall = settings.wall;
  if (!quiet)
    for (std::size_t n = 0; n < surfaces.size(); ++n)
      std::printf("sink: %s%s\n", walls::describeSurface(surfaces[n], int(n)).c_str(),
                  int(n) == o.surface ? " (shown)" : "");
  if (!quiet)
    std::printf("sink: wall '%s', %zu display(s), virtual screen %dx%d; listening on %s:%u%s\n",
                wall.id.c_str(), wall.displays.size(), wall.width, wall.height,
                settings.listenHost.c_str(), unsigned(sink.port()),
                settings.token.empty() ? "" : " (token required)");
  if (!quiet && sink.httpPort())
    std::printf(
        "sink: wall page at http://%s:%u/%s\n",
        settings.httpHost.find(':') != std::string::npos ? ("[" + settings.httpHost + "]").c_str()
                                                         : settings.httpHost.c_str(),
        unsigned(sink.httpPort()), settings.token.empty() ? "" : " (it asks for the token)");
  std::fflush(stdout);

  std::thread signalWatcher([sinkPtr, signals] {
    int received = 0;
    sigwait(&signals, &received);
    sinkPtr->stop();
  });
  signalWatcher.detach();  // blocked in sigwait until a signal; the process exits after run()
  if (!o.noStdin) {
    // Camera commands typed at the sink go to the render job's rank 0.
    std::thread([sinkPtr, quiet] {
      std::string line;
      while (std::getline(std::cin, line)) {
        if (line.find_first_not_of(" \t") == std::string::npos) continue;
        try {
          sinkPtr->sendControl(walls::parseControlLine(line));
        } catch (const std::invalid_argument& e) {
          if (!quiet) std::fprintf(stderr, "sink: %s\n", e.what());
        }
      }
    }).detach();
  }
  sink.run();
  const auto st = sink.stats();
  if (!quiet)
    std::printf(
        "sink: %d frame(s) presented, %d dropped incomplete, %d skipped (behind); "
        "%d refused (frame id outside the window); "
        "peers: %d accepted, %d refused, %d dropped; %s received; mean latency %.1f ms\n",
        st.framesPresented, st.framesDropped, st.framesStale, st.framesRefused, st.peersAccepted,
        st.peersRefused, st.peersDropped, humanBytes(double(st.bytesReceived)).c_str(),
        st.meanLatencyMs);
}

}  // namespace

void addSinkCommand(CLI::App& app) {
  auto o = std::make_shared<SinkOptions>();
  auto* cmd = app.add_subcommand(
      "sink",
      "The display wall's data sink: accepts the tiles that `voxwall render --sink` streams, "
      "shows (writes) a frame only when every display pixel has arrived, and forwards camera "
      "commands typed on stdin (rotate DAZ DEL | zoom FACTOR | pan DX DY | reset) to the render "
      "job");
  cmd->add_option("--wall", o->wall, "Wall file (walls/*.json, or a Tide configuration)")
      ->required();
  cmd->add_option("--surface", o->surface,
                  "Which surface of a Tide configuration with several to show (0: the first; "
                  "the sink lists them when it starts)")
      ->capture_default_str();
  cmd->add_option("--listen", o->listen,
                  "Address and port to listen on (loopback by default; 0.0.0.0:PORT for all)")
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Write every presented frame as DIR/frame_NNNNN_<display>.png");
  cmd->add_flag("--mosaic", o->mosaic, "Also write the whole virtual screen, bezels included");
  cmd->add_option("--token", o->token,
                  "Refuse peers that do not present this token (it travels in clear text: "
                  "tunnel the port through SSH or keep it on a private network)");
  cmd->add_option("--frames", o->frames,
                  "Exit after this many frames were presented, skipped (the sink fell behind) or "
                  "dropped (incomplete); 0: run until interrupted")
      ->capture_default_str();
  cmd->add_option("--pending", o->pending,
                  "Incomplete frames held at once before the oldest is dropped")
      ->capture_default_str();
  cmd->add_option("--pending-mib", o->pendingMiB,
                  "Memory for tiles of incomplete frames; when it is full the oldest frame is "
                  "dropped (default 0: two frames of this wall plus 64 MiB)")
      ->capture_default_str();
  cmd->add_option("--max-peers", o->maxPeers,
                  "Connections at once (ranks, rank 0's control, not yet greeted); more are "
                  "refused")
      ->capture_default_str();
  cmd->add_option("--hello-timeout-ms", o->helloTimeoutMs,
                  "Drop a peer that has not said Hello by then")
      ->capture_default_str();
  cmd->add_option("--http", o->http,
                  "Serve the wall page at HOST:PORT (e.g. 127.0.0.1:8080): the live wall, the "
                  "load balancer's rectangles, and camera control by mouse and touch. Loopback is "
                  "the safe choice: reach it through an SSH tunnel (ssh -L 8080:127.0.0.1:8080 "
                  "wallhost). With --token the page asks for it");
  cmd->add_option("--http-origin", o->httpOrigins,
                  "Another Origin whose pages may use the wall page's WebSocket (e.g. "
                  "http://localhost:8080 when tunnelled under another name); repeatable");
  cmd->add_option("--max-viewers", o->maxViewers, "Browsers watching at once; more are refused")
      ->capture_default_str();
  cmd->add_flag("--no-stdin", o->noStdin, "Do not read camera commands from stdin");
  cmd->add_flag("-q,--quiet", o->quiet, "Print nothing but errors");
  cmd->callback([o] { runSink(*o); });
}

}  // namespace voxwall::cli
