#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>
#include <thread>
#include <voxwall/core/text.hpp>
#include <voxwall/walls/sink.hpp>

#include "../cli_common.hpp"
#include "commands.hpp"
#include "sink_settings.hpp"

namespace voxwall::cli {
namespace {

void printBanner(const SinkOptions& o, const walls::SinkSettings& s, const walls::Sink& sink) {
  const auto& wall = s.wall;
  const auto surfaces = walls::loadWalls(o.wall);
  for (std::size_t n = 0; n < surfaces.size(); ++n)
    std::printf("sink: %s%s\n", walls::describeSurface(surfaces[n], int(n)).c_str(),
                int(n) == o.surface ? " (shown)" : "");
  std::printf("sink: wall '%s', %zu display(s), virtual screen %dx%d; listening on %s:%u%s\n",
              wall.id.c_str(), wall.displays.size(), wall.width, wall.height, s.listenHost.c_str(),
              unsigned(sink.port()), s.token.empty() ? "" : " (token required)");
  if (sink.httpPort()) {
    const std::string host =
        s.httpHost.find(':') != std::string::npos ? "[" + s.httpHost + "]" : s.httpHost;
    const std::string base = "http://" + host + ":" + std::to_string(sink.httpPort());
    std::printf("sink: wall page at %s/%s\n", base.c_str(),
                s.token.empty() ? "" : " (it asks for the token)");
    std::printf(
        "sink: display pages at %s/display/<name>, listed with launch lines at "
        "%s/displays\n",
        base.c_str(), base.c_str());
  }
  std::fflush(stdout);
}

void printSummary(const walls::SinkStats& st) {
  std::printf(
      "sink: %d frame(s) presented, %d dropped incomplete, %d refused (frame id outside the "
      "window); %d written, %d not written (the writer fell behind or a tile did not decode); "
      "%d switched together on the display pages; peers: %d accepted, %d refused, %d dropped; "
      "%s received; mean latency %.1f ms\n",
      st.framesPresented, st.framesDropped, st.framesRefused, st.framesWritten, st.framesNotWritten,
      st.framesSwapped, st.peersAccepted, st.peersRefused, st.peersDropped,
      humanBytes(double(st.bytesReceived)).c_str(), st.meanLatencyMs);
}

void runSink(const SinkOptions& o) {
  const auto settings = sinkSettings(o);
  // SIGINT and SIGTERM end the sink cleanly (the frames presented are written first).
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  const bool quiet = o.quiet;
  // Shared with the detached threads below, which may outlive this function until exit.
  const auto sink = std::make_shared<walls::Sink>(settings, [quiet](const std::string& line) {
    if (quiet) return;
    std::printf("%s\n", line.c_str());
    std::fflush(stdout);
  });
  if (!quiet) printBanner(o, settings, *sink);
  std::thread([sink, signals] {
    int received = 0;
    sigwait(&signals, &received);
    sink->stop();
  }).detach();  // blocked in sigwait until a signal; the process exits after run()
  if (!o.noStdin)
    // Camera commands typed at the sink go to the render job's rank 0.
    std::thread([sink, quiet] {
      std::string line;
      while (std::getline(std::cin, line)) {
        if (line.find_first_not_of(" \t") == std::string::npos) continue;
        try {
          sink->sendControl(walls::parseControlLine(line));
        } catch (const std::invalid_argument& e) {
          if (!quiet) std::fprintf(stderr, "sink: %s\n", e.what());
        }
      }
    }).detach();
  sink->run();
  if (!quiet) printSummary(sink->stats());
}

}  // namespace

void addSinkCommand(CLI::App& app) {
  auto o = std::make_shared<SinkOptions>();
  auto* cmd = app.add_subcommand(
      "sink",
      "The display wall's data sink: accepts the tiles that `voxwall render --sink` streams, "
      "presents a frame only when every display pixel has arrived, routes each display's "
      "segments to that display's page (--http; every display switches together), writes "
      "frames (--out), and forwards commands typed on stdin to the render job: camera (rotate "
      "DAZ DEL | zoom FACTOR | pan DX DY | reset) and, for a time series, time (play | pause | "
      "step N | seek STEP)");
  addSinkOptions(*cmd, *o);
  cmd->callback([o] { runSink(*o); });
}

}  // namespace voxwall::cli
