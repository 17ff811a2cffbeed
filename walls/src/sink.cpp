// The sink's transport and router: a net::Server on one Asio thread feeds each peer's checked
// messages to the SinkCore. Per frame: collecting -> complete (every display pixel covered) ->
// presented: its segments go to the displays' pages and the overview (web_view.hpp) and, with
// --out, to the file writer's queue (frame_files.hpp), all without waiting; or dropped (a newer
// frame completed first, too many frames were open, the memory limit) or refused (outside the
// frame window). Every outcome is logged and told to rank 0.
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <regex>
#include <sstream>
#include <vector>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/text.hpp>
#include <voxwall/net/asio.hpp>
#include <voxwall/net/server.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/frame_files.hpp>
#include <voxwall/walls/log_throttle.hpp>
#include <voxwall/walls/sink.hpp>
#include <voxwall/walls/sink_core.hpp>
#include <voxwall/walls/web_view.hpp>

namespace voxwall::walls {

struct Sink::Impl : net::PeerHandler {
  SinkSettings settings;
  SinkLog log;
  asio::io_context io;
  std::unique_ptr<SinkCore> core;
  std::unique_ptr<net::Server> server;
  std::unique_ptr<WebView> web;             // the pages, when asked for
  std::unique_ptr<FrameFileWriter> writer;  // --out
  std::string writeError;                   // the first frame that could not be written ends it
  double latencySumMs = 0;

  void say(const std::string& line) {
    if (log) log(line);
  }

  // After maxFrames frames were settled (presented or dropped), the sink stops.
  void stopIfDone() {
    const auto s = core->stats();
    const int settled = s.framesPresented + s.framesDropped + s.framesSuperseded;
    if (settings.maxFrames > 0 && settled >= settings.maxFrames)
      asio::post(io, [this] { io.stop(); });
  }

  // net::PeerHandler: the server's peers go to the core; every message may settle the last frame.
  void attach(net::Peer& peer) override { core->attach(peer); }
  void detach(net::Peer& peer) override { core->detach(peer); }
  std::uint32_t payloadLimit(const net::Peer& peer) const override {
    return core->payloadLimit(peer);
  }
  bool handle(net::Peer& peer, net::MessageType type, std::uint64_t frame,
              std::span<const std::byte> payload) override {
    const bool goOn = core->handle(peer, type, frame, payload);
    stopIfDone();
    return goOn;
  }
  void refuse(net::Peer& peer, const std::string& reason) override { core->refuse(peer, reason); }
  void dropped(net::Peer& peer, const std::string& why) override { core->dropped(peer, why); }
  void received(std::uint64_t bytes) override {
    core->updateStats([&](SinkStats& s) { s.bytesReceived += bytes; });
  }
  // Logged at most once every 10 s, with the count since: a flood of connections must not flood
  // the log.
  void refusedConnection(const std::string& why) override {
    core->updateStats([](SinkStats& s) { ++s.peersRefused; });
    const std::string line = refusals.line("connection", "sink: refused a connection: " + why);
    if (!line.empty()) say(line);
  }
  LogThrottle refusals;

  // On the io thread: a complete frame is presented at once. Nothing here decodes or writes.
  void onComplete(std::uint64_t job, AssembledFrame&& data) {
    const auto frame = std::make_shared<const AssembledFrame>(std::move(data));
    const double latencyMs = frame->decidedUnixMicros
                                 ? double(net::unixMicrosNow() - frame->decidedUnixMicros) / 1e3
                                 : 0.0;
    core->updateStats([&](SinkStats& s) {
      const int presented = ++s.framesPresented;
      latencySumMs += latencyMs;
      s.meanLatencyMs = latencySumMs / presented;
    });
    char line[256];
    const std::string label = net::stepLabel(frame->step, frame->phase);
    const std::string interactive = label.empty() ? label : ", " + label;
    std::snprintf(line, sizeof line,
                  "frame %llu presented: %zu display(s), %d tiles from %zu rank(s), %.1f KiB, "
                  "latency %.1f ms%s",
                  (unsigned long long)frame->frame, settings.wall.displays.size(), frame->tiles,
                  frame->rankRenderMicros.size(), double(frame->bytes) / 1024, latencyMs,
                  interactive.c_str());
    say(line);
    core->frameSettled(job, frame->frame, {net::FrameStatus::Presented, ""});
    if (web) web->present({frame, latencyMs, core->stats()});
    if (writer) writer->push(job, frame);
    stopIfDone();
  }

  // The file writer's word on a frame (on its thread, or on the io thread for a skip).
  void onWritten(std::uint64_t job, std::uint64_t frame, FrameFileWriter::Outcome outcome,
                 const std::string& why) {
    using Outcome = FrameFileWriter::Outcome;
    core->updateStats([&](SinkStats& s) {
      if (outcome == Outcome::Written) ++s.framesWritten;
      if (outcome == Outcome::Skipped) ++s.framesNotWritten;
    });
    if (outcome == Outcome::Written) return;
    say("frame " + std::to_string(frame) + " " +
        (outcome == Outcome::Failed ? "not written: " + why : why));
    if (outcome == Outcome::Failed)
      // A full disk loses every later frame too: stop, and say so.
      asio::post(io, [this, job, frame, why] {
        core->frameSettled(job, frame, {net::FrameStatus::Dropped, "not written: " + why});
        if (writeError.empty()) writeError = why;
        io.stop();
      });
  }
};

Sink::Sink(SinkSettings settings, SinkLog log) : impl_(std::make_unique<Impl>()) {
  auto& s = *impl_;
  s.settings = std::move(settings);
  s.log = std::move(log);
  validateWall(s.settings.wall, "wall");
  if (s.settings.pendingFrames < 1) s.settings.pendingFrames = 1;
  s.core = std::make_unique<SinkCore>(
      s.settings, s.log,
      [this](std::uint64_t job, AssembledFrame&& f) { impl_->onComplete(job, std::move(f)); });
  s.server = std::make_unique<net::Server>(
      s.io,
      net::ServerSettings{s.settings.listenHost, s.settings.listenPort, s.settings.maxPeers,
                          s.settings.helloTimeoutMs, s.settings.peerIdleMs},
      s, s.log);
  if (!s.settings.outDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(s.settings.outDir, ec);
    if (ec) throw FormatError(s.settings.outDir, "cannot create: " + ec.message());
    if (const int removed = removeIncompleteFrames(s.settings.outDir))
      s.say("sink: removed " + std::to_string(removed) + " file(s) of incomplete frames from " +
            s.settings.outDir);
    FrameFileSettings files;
    files.mosaic = s.settings.mosaic;
    files.format = s.settings.outFormat;
    s.writer = std::make_unique<FrameFileWriter>(
        s.settings.outDir, s.settings.wall, files, s.settings.writeQueue,
        [this](std::uint64_t job, std::uint64_t frame, FrameFileWriter::Outcome outcome,
               const std::string& why) { impl_->onWritten(job, frame, outcome, why); });
  }
  if (!s.settings.httpHost.empty()) {
    WebViewSettings web;
    web.host = s.settings.httpHost;
    web.port = s.settings.httpPort;
    web.token = s.settings.token;
    web.origins = s.settings.httpOrigins;
    web.maxViewers = s.settings.maxViewers;
    web.maxDisplayPages = s.settings.maxDisplayPages;
    web.swapTimeoutMs = s.settings.swapTimeoutMs;
    web.swapLeadMs = s.settings.swapLeadMs;
    web.authTimeoutMs = s.settings.viewerAuthTimeoutMs;
    web.writeTimeoutMs = s.settings.viewerWriteTimeoutMs;
    s.web = std::make_unique<WebView>(
        s.settings.wall, web, [this](const net::Control& c) { sendControl(c); }, s.log,
        [this](const WebView::SwapStats& swap) {
          impl_->core->updateStats([&](SinkStats& st) {
            st.displayPages = swap.pages;
            st.displayPagesInBarrier = swap.inBarrier;
            st.framesSwapped = swap.framesSwapped;
            st.lastSwapSpreadMs = swap.lastSpreadMs;
          });
        });
  }
}

Sink::~Sink() {
  if (impl_->web) impl_->web->stop();
  impl_->writer.reset();  // finishes the frames queued
}

std::uint16_t Sink::port() const { return impl_->server->port(); }
std::uint16_t Sink::httpPort() const { return impl_->web ? impl_->web->port() : 0; }

void Sink::run() {
  impl_->server->start();
  if (impl_->web) impl_->web->start();
  impl_->io.run();
  // Stop listening and hang up on every peer, so the port is free for a new sink at once.
  impl_->server->close();
  // Write the frames presented so far before returning.
  if (impl_->writer) impl_->writer->drain();
  if (impl_->web) impl_->web->stop();
  // Handlers the writer posted last (a write error) still run here.
  impl_->io.restart();
  impl_->io.poll();
  if (!impl_->writeError.empty()) throw FormatError("", impl_->writeError);
}

void Sink::stop() {
  asio::post(impl_->io, [this] { impl_->io.stop(); });
}

void Sink::sendControl(const net::Control& control) {
  asio::post(impl_->io, [this, control] {
    if (const std::string why = impl_->core->sendControl(control); !why.empty())
      impl_->say("sink: " + why);
  });
}

SinkStats Sink::stats() const { return impl_->core->stats(); }

net::Control parseControlLine(const std::string& line) {
  // The whole line, word by word (spaces or tabs between them): a command and exactly its numbers.
  std::vector<std::string> words;
  std::string word;
  for (const char ch : line) {
    if (ch == ' ' || ch == '\t') {
      if (!word.empty()) words.push_back(std::move(word)), word.clear();
    } else {
      word += ch;
    }
  }
  if (!word.empty()) words.push_back(std::move(word));
  const std::string usage =
      "commands: rotate DAZ DEL | zoom FACTOR | pan DX DY | reset | play | pause | step N | "
      "seek STEP";
  const std::string quoted = quotedForLog(line);
  // Decimal numbers only (strtod also takes hexadecimal, "inf" and "nan"); a value too small
  // for a double (4.9e-324) is that small value, not an error.
  auto number = [&](const std::string& text) {
    static const std::regex decimal(R"([+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?)");
    double v = 0;
    bool ok = std::regex_match(text, decimal);
    if (ok) {
      errno = 0;
      v = std::strtod(text.c_str(), nullptr);
      ok = errno != ERANGE || std::abs(v) < 1;
    }
    if (!ok || !std::isfinite(v) || std::abs(v) > 1e6)
      throw std::invalid_argument(quoted + ": " + quotedForLog(text, 24) +
                                  " is not a number within +-1e6 (" + usage + ")");
    return v;
  };
  struct Form {
    const char* name;
    net::ControlCommand command;
    std::size_t args;
  };
  static constexpr Form kForms[] = {
      {"rotate", net::ControlCommand::Rotate, 2}, {"zoom", net::ControlCommand::Zoom, 1},
      {"pan", net::ControlCommand::Pan, 2},       {"reset", net::ControlCommand::Reset, 0},
      {"play", net::ControlCommand::Play, 0},     {"pause", net::ControlCommand::Pause, 0},
      {"step", net::ControlCommand::StepBy, 1},   {"seek", net::ControlCommand::Seek, 1}};
  const std::string name = words.empty() ? "" : words[0];
  const auto form = std::find_if(std::begin(kForms), std::end(kForms),
                                 [&](const Form& f) { return name == f.name; });
  if (form == std::end(kForms)) throw std::invalid_argument(quoted + ": " + usage);
  net::Control c;
  c.command = form->command;
  const std::size_t args = form->args;
  if (words.size() != args + 1)
    throw std::invalid_argument(quoted + ": " + name + " takes " + std::to_string(args) +
                                (args == 1 ? " number" : " numbers") + " (" + usage + ")");
  if (args >= 1) c.a = number(words[1]);
  if (args >= 2) c.b = number(words[2]);
  if (const auto why = net::controlProblem(c); !why.empty())
    throw std::invalid_argument(quoted + ": " + why);
  return c;
}

}  // namespace voxwall::walls
