// The sink's transport: one Asio thread accepts peers, reads each message (header, then the
// payload in chunks as it arrives, checked) and hands it to the SinkCore; a presenter thread
// writes complete frames. Per frame: collecting -> complete (every display pixel covered) ->
// presented, or dropped (a newer frame completed first, too many frames were open, the memory
// limit) or refused (outside the frame window); every outcome is logged and told to rank 0.
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <asio.hpp>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>
#include <voxwall/codec/errors.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/frame_files.hpp>
#include <voxwall/walls/sink.hpp>
#include <voxwall/walls/sink_core.hpp>

namespace voxwall::walls {

using asio::ip::tcp;

namespace {

struct CompleteFrame {
  std::uint64_t job = 0;
  AssembledFrame data;
};

constexpr std::size_t kPayloadChunk = 1 << 20;  // a payload's memory grows as its bytes arrive

}  // namespace

struct Sink::Impl {
  struct Session;

  SinkSettings settings;
  SinkLog log;
  asio::io_context io;
  tcp::acceptor acceptor{io};
  asio::steady_timer acceptPause{io};
  std::unique_ptr<SinkCore> core;
  std::set<std::shared_ptr<Session>> sessions;

  // Presenter: the newest complete frame waits here; a newer one replaces it (stale).
  std::mutex presentMutex;
  std::condition_variable presentReady;
  std::optional<CompleteFrame> toPresent;
  bool presenterStop = false;
  std::thread presenter;
  std::string writeError;  // the first frame that could not be written ends the sink
  double latencySumMs = 0;

  void say(const std::string& line) {
    if (log) log(line);
  }

  // After maxFrames frames were settled (presented, skipped or dropped), the sink stops.
  void stopIfDone() {
    const auto s = core->stats();
    const int settled = s.framesPresented + s.framesStale + s.framesDropped;
    if (settings.maxFrames > 0 && settled >= settings.maxFrames)
      asio::post(io, [this] { io.stop(); });
  }

  struct Session : SinkPeer, std::enable_shared_from_this<Session> {
    Impl& sink;
    tcp::socket socket;
    asio::steady_timer helloDeadline;
    std::array<std::byte, net::kHeaderBytes> header{};
    std::vector<std::byte> payload;
    std::uint32_t payloadBytes = 0;
    net::MessageType type{};
    std::uint64_t frame = 0;
    bool closing = false, closed = false;
    std::deque<std::vector<std::byte>> outbox;

    static std::string nameOf(tcp::socket& socket) {
      asio::error_code ec;
      const auto ep = socket.remote_endpoint(ec);
      return ec ? std::string("peer")
                : "peer " + ep.address().to_string() + ":" + std::to_string(ep.port());
    }

    Session(Impl& s, tcp::socket sock)
        : SinkPeer(nameOf(sock)), sink(s), socket(std::move(sock)), helloDeadline(s.io) {}

    void start() {
      sink.core->attach(*this);
      auto self = shared_from_this();
      helloDeadline.expires_after(std::chrono::milliseconds(sink.settings.helloTimeoutMs));
      helloDeadline.async_wait([self](asio::error_code ec) {
        if (ec || self->greeted() || self->closed) return;
        self->drop("sent no Hello within " + std::to_string(self->sink.settings.helloTimeoutMs) +
                   " ms");
      });
      readHeader();
    }

    void readHeader() {
      auto self = shared_from_this();
      asio::async_read(socket, asio::buffer(header), [self](asio::error_code ec, std::size_t) {
        if (self->closed) return;
        if (ec) return self->drop(ec == asio::error::eof ? "" : ec.message());
        try {
          self->payloadBytes =
              net::checkHeader(self->header, self->name(), &self->type, &self->frame);
        } catch (const FormatError& e) {
          return self->refuse(e.what());
        }
        const std::uint32_t limit = self->sink.core->payloadLimit(*self);
        if (self->payloadBytes > limit)
          return self->refuse(self->name() + ": payload of " + std::to_string(self->payloadBytes) +
                              " bytes" + (self->greeted() ? "" : " before its Hello") + " (limit " +
                              std::to_string(limit) + ")");
        self->payload.clear();
        self->readPayload();
      });
    }

    // Reads the payload a chunk at a time: memory follows the bytes that really arrived, not
    // the length a header claims.
    void readPayload() {
      if (payload.size() == payloadBytes) return onMessage();
      const std::size_t have = payload.size();
      const std::size_t chunk = std::min<std::size_t>(payloadBytes - have, kPayloadChunk);
      payload.resize(have + chunk);
      auto self = shared_from_this();
      asio::async_read(
          socket, asio::buffer(payload.data() + have, chunk),
          [self](asio::error_code ec, std::size_t) {
            if (self->closed) return;
            if (ec) return self->drop(ec == asio::error::eof ? "closed mid-message" : ec.message());
            self->readPayload();
          });
    }

    void onMessage() {
      sink.core->updateStats(
          [&](SinkStats& s) { s.bytesReceived += net::kHeaderBytes + payload.size(); });
      try {
        net::checkPayload(header, payload, name());
        const bool goOn = sink.core->handle(*this, type, frame, payload);
        sink.stopIfDone();
        if (!goOn) return;
      } catch (const FormatError& e) {
        return drop(e.what());
      }
      if (closed) return;  // the core hung up on this peer (another job took the wall)
      readHeader();
    }

    void send(std::vector<std::byte> bytes) override {
      if (closed) return;
      outbox.push_back(std::move(bytes));
      if (outbox.size() == 1) writeNext();
    }

    void hangUp() override {
      closing = true;
      if (outbox.empty()) close();
    }

    void writeNext() {
      auto self = shared_from_this();
      asio::async_write(socket, asio::buffer(outbox.front()),
                        [self](asio::error_code ec, std::size_t) {
                          if (self->closed) return;
                          self->outbox.pop_front();
                          if (ec) return self->drop(ec.message());
                          if (!self->outbox.empty()) return self->writeNext();
                          if (self->closing) self->close();
                        });
    }

    void refuse(const std::string& reason) { sink.core->refuse(*this, reason); }

    void drop(const std::string& why) {
      if (closed) return;
      sink.core->dropped(*this, why);
      close();
    }

    void close() {
      if (closed) return;
      closed = true;
      sink.core->detach(*this);
      asio::error_code ignored;
      helloDeadline.cancel();
      socket.shutdown(tcp::socket::shutdown_both, ignored);
      socket.close(ignored);
      sink.sessions.erase(shared_from_this());
    }
  };

  void accept() {
    acceptor.async_accept([this](asio::error_code ec, tcp::socket socket) {
      if (!acceptor.is_open() || ec == asio::error::operation_aborted) return;
      if (ec) {
        // Out of file descriptors (EMFILE/ENFILE) or a peer gone before accept: keep serving,
        // after a pause that lets idle peers time out.
        say("sink: cannot accept a peer: " + ec.message() + "; retrying in 100 ms");
        acceptPause.expires_after(std::chrono::milliseconds(100));
        acceptPause.async_wait([this](asio::error_code e) {
          if (!e) accept();
        });
        return;
      }
      asio::error_code ignored;
      if (int(sessions.size()) >= settings.maxPeers) {
        core->updateStats([](SinkStats& s) { ++s.peersRefused; });
        say("sink: refused a peer: " + std::to_string(settings.maxPeers) +
            " peers connected (--max-peers)");
        socket.close(ignored);
        return accept();
      }
      socket.set_option(tcp::no_delay(true), ignored);
      // A render host that vanishes (power, network) leaves a half-open connection that would
      // hold the wall for its job forever: TCP keep-alive closes it within about a minute.
      socket.set_option(asio::socket_base::keep_alive(true), ignored);
      for (const auto& [option, value] :
           {std::pair{TCP_KEEPIDLE, 30}, std::pair{TCP_KEEPINTVL, 10}, std::pair{TCP_KEEPCNT, 3}})
        ::setsockopt(socket.native_handle(), IPPROTO_TCP, option, &value, sizeof value);
      auto session = std::make_shared<Session>(*this, std::move(socket));
      sessions.insert(session);
      session->start();
      accept();
    });
  }

  // On the io thread: a complete frame goes to the presenter (replacing one it has not taken).
  void onComplete(std::uint64_t job, AssembledFrame&& frame) {
    std::lock_guard lock(presentMutex);
    if (toPresent) {
      const auto skipped = toPresent->data.frame;
      say("frame " + std::to_string(skipped) + " skipped: the sink fell behind");
      core->updateStats([](SinkStats& s) { ++s.framesStale; });
      core->frameSettled(toPresent->job, skipped,
                         {net::FrameStatus::Dropped, "skipped: the sink fell behind"});
      stopIfDone();
    }
    toPresent = CompleteFrame{job, std::move(frame)};
    presentReady.notify_one();
  }

  void present() {
    for (;;) {
      CompleteFrame frame;
      {
        std::unique_lock lock(presentMutex);
        presentReady.wait(lock, [&] { return presenterStop || toPresent; });
        if (!toPresent) return;
        frame = std::move(*toPresent);
        toPresent.reset();
      }
      const auto& wall = settings.wall;
      const auto number = frame.data.frame;
      if (!settings.outDir.empty()) {
        try {
          writeFrameFiles(settings.outDir, number, wall, frame.data.image, settings.mosaic);
        } catch (const std::exception& e) {
          // A full disk loses every later frame too: stop, and say so.
          say("frame " + std::to_string(number) + " not presented: " + e.what());
          asio::post(io, [this, job = frame.job, number, why = std::string(e.what())] {
            core->frameSettled(job, number, {net::FrameStatus::Dropped, "not written: " + why});
            if (writeError.empty()) writeError = why;
            io.stop();
          });
          return;
        }
      }
      const double latencyMs =
          frame.data.decidedUnixMicros
              ? double(net::unixMicrosNow() - frame.data.decidedUnixMicros) / 1e3
              : 0.0;
      core->updateStats([&](SinkStats& s) {
        const int presented = ++s.framesPresented;
        latencySumMs += latencyMs;
        s.meanLatencyMs = latencySumMs / presented;
      });
      char line[256];
      std::snprintf(line, sizeof line,
                    "frame %llu presented: %zu display(s), %d tiles from %zu rank(s), %.1f KiB, "
                    "latency %.1f ms",
                    (unsigned long long)number, wall.displays.size(), frame.data.tiles,
                    frame.data.ranks.size(), double(frame.data.bytes) / 1024, latencyMs);
      say(line);
      asio::post(io, [this, job = frame.job, number] {
        core->frameSettled(job, number, {net::FrameStatus::Presented, ""});
      });
      stopIfDone();
    }
  }

  void stopPresenter() {
    {
      std::lock_guard lock(presentMutex);
      presenterStop = true;
    }
    presentReady.notify_all();
    if (presenter.joinable()) presenter.join();
  }
};

Sink::Sink(SinkSettings settings, SinkLog log) : impl_(std::make_unique<Impl>()) {
  auto& s = *impl_;
  s.settings = std::move(settings);
  s.log = std::move(log);
  validateWall(s.settings.wall, "wall");
  if (s.settings.pendingFrames < 1) s.settings.pendingFrames = 1;
  if (s.settings.maxPeers < 1) throw std::invalid_argument("--max-peers must be at least 1");
  if (s.settings.helloTimeoutMs < 1)
    throw std::invalid_argument("the Hello timeout must be positive");
  s.core = std::make_unique<SinkCore>(
      s.settings, s.log,
      [this](std::uint64_t job, AssembledFrame&& f) { impl_->onComplete(job, std::move(f)); });
  if (!s.settings.outDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(s.settings.outDir, ec);
    if (ec) throw FormatError(s.settings.outDir, "cannot create: " + ec.message());
    if (const int removed = removeIncompleteFrames(s.settings.outDir))
      s.say("sink: removed " + std::to_string(removed) + " file(s) of incomplete frames from " +
            s.settings.outDir);
  }
  asio::error_code ec;
  const auto address = asio::ip::make_address(s.settings.listenHost, ec);
  if (ec) throw net::NetError("--listen: '" + s.settings.listenHost + "' is not an IP address");
  const tcp::endpoint endpoint(address, s.settings.listenPort);
  s.acceptor.open(endpoint.protocol(), ec);
  if (!ec) s.acceptor.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) s.acceptor.bind(endpoint, ec);
  if (!ec) s.acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    throw net::NetError("cannot listen on " + s.settings.listenHost + ":" +
                        std::to_string(s.settings.listenPort) + ": " + ec.message());
  s.presenter = std::thread([this] { impl_->present(); });
}

Sink::~Sink() { impl_->stopPresenter(); }

std::uint16_t Sink::port() const { return impl_->acceptor.local_endpoint().port(); }

void Sink::run() {
  impl_->accept();
  impl_->io.run();
  // Stop listening and hang up on every peer, so the port is free for a new sink at once.
  asio::error_code ignored;
  impl_->acceptor.close(ignored);
  impl_->acceptPause.cancel();
  for (const auto& session : std::set(impl_->sessions)) session->close();
  impl_->sessions.clear();
  // Finish the frame being written before returning.
  impl_->stopPresenter();
  // Handlers the presenter posted last (its frame notes, a write error) still run here.
  impl_->io.restart();
  impl_->io.poll();
  if (!impl_->writeError.empty()) throw FormatError("", impl_->writeError);
}

void Sink::stop() {
  asio::post(impl_->io, [this] { impl_->io.stop(); });
}

void Sink::sendControl(const net::Control& control) {
  asio::post(impl_->io, [this, control] {
    if (!impl_->core->sendControl(control))
      impl_->say("sink: no render job connected to take the command");
  });
}

SinkStats Sink::stats() const { return impl_->core->stats(); }

net::Control parseControlLine(const std::string& line) {
  std::istringstream in(line);
  std::string word;
  in >> word;
  net::Control c;
  double a = 0, b = 0;
  const std::string usage = "commands: rotate DAZ DEL | zoom FACTOR | pan DX DY | reset";
  if (word == "rotate" && (in >> a >> b)) {
    c.command = net::ControlCommand::Rotate;
  } else if (word == "zoom" && (in >> a) && a > 0) {
    c.command = net::ControlCommand::Zoom;
  } else if (word == "pan" && (in >> a >> b)) {
    c.command = net::ControlCommand::Pan;
  } else if (word == "reset") {
    c.command = net::ControlCommand::Reset;
  } else {
    throw std::invalid_argument("'" + line + "': " + usage);
  }
  if (!std::isfinite(a) || !std::isfinite(b) || std::abs(a) > 1e6 || std::abs(b) > 1e6)
    throw std::invalid_argument("'" + line + "': values out of range");
  c.a = a, c.b = b;
  return c;
}

}  // namespace voxwall::walls
