// The sink: one Asio thread reads every peer (header, then payload, checked), decodes tiles into
// the frame they belong to and marks which display pixels have arrived; a presenter thread
// writes complete frames. Per frame: collecting -> complete (every display pixel covered) ->
// presented, or dropped (a newer frame completed first, or too many frames were open).
#include <asio.hpp>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>
#include <voxwall/codec/errors.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/walls/sink.hpp>

namespace voxwall::walls {

using asio::ip::tcp;

namespace {

struct PendingFrame {
  node::Image image;
  std::vector<std::uint8_t> covered;  // per virtual-screen pixel
  long long coveredDisplayPixels = 0;
  std::uint64_t decidedUnixMicros = 0, bytes = 0;
  int tiles = 0;
  std::set<int> ranks;
};

struct CompleteFrame {
  std::uint64_t frame = 0;
  PendingFrame data;
};

}  // namespace

struct Sink::Impl {
  struct Session;

  SinkSettings settings;
  SinkLog log;
  asio::io_context io;
  tcp::acceptor acceptor{io};
  std::vector<std::uint8_t> displayMask;  // 1 inside a display
  std::map<std::uint64_t, PendingFrame> pending;
  std::optional<std::uint64_t> lastComplete;
  std::weak_ptr<Session> controller;
  std::set<std::shared_ptr<Session>> sessions;

  mutable std::mutex statsMutex;
  SinkStats stats;
  double latencySumMs = 0;

  // Presenter: the newest complete frame waits here; a newer one replaces it (stale).
  std::mutex presentMutex;
  std::condition_variable presentReady;
  std::optional<CompleteFrame> toPresent;
  bool presenterStop = false;
  std::thread presenter;

  void say(const std::string& line) {
    if (log) log(line);
  }

  // After maxFrames frames were settled (presented, skipped or dropped), the sink stops.
  // Call with statsMutex held.
  void stopIfDone() {
    const int settled = stats.framesPresented + stats.framesStale + stats.framesDropped;
    if (settings.maxFrames > 0 && settled >= settings.maxFrames)
      asio::post(io, [this] { io.stop(); });
  }

  struct Session : std::enable_shared_from_this<Session> {
    Impl& sink;
    tcp::socket socket;
    std::string name;
    std::array<std::byte, net::kHeaderBytes> header{};
    std::vector<std::byte> payload;
    net::MessageType type{};
    std::uint64_t frame = 0;
    bool greeted = false, closing = false;
    net::Hello hello;
    std::deque<std::vector<std::byte>> outbox;

    Session(Impl& s, tcp::socket sock) : sink(s), socket(std::move(sock)) {
      asio::error_code ec;
      const auto ep = socket.remote_endpoint(ec);
      name = ec ? std::string("peer")
                : "peer " + ep.address().to_string() + ":" + std::to_string(ep.port());
    }

    void readHeader() {
      auto self = shared_from_this();
      asio::async_read(socket, asio::buffer(header), [self](asio::error_code ec, std::size_t) {
        if (ec) return self->drop(ec == asio::error::eof ? "" : ec.message());
        std::uint32_t length = 0;
        try {
          length = net::checkHeader(self->header, self->name, &self->type, &self->frame);
        } catch (const FormatError& e) {
          return self->refuse(e.what());
        }
        self->payload.resize(length);
        self->readPayload();
      });
    }

    void readPayload() {
      auto self = shared_from_this();
      asio::async_read(socket, asio::buffer(payload), [self](asio::error_code ec, std::size_t) {
        if (ec) return self->drop(ec == asio::error::eof ? "closed mid-message" : ec.message());
        {
          std::lock_guard lock(self->sink.statsMutex);
          self->sink.stats.bytesReceived += net::kHeaderBytes + self->payload.size();
        }
        try {
          net::checkPayload(self->header, self->payload, self->name);
          if (!self->handle()) return;
        } catch (const FormatError& e) {
          return self->drop(e.what());
        }
        self->readHeader();
      });
    }

    // Returns false when the session ends.
    bool handle() {
      using net::MessageType;
      if (!greeted) {
        if (type != MessageType::Hello) {
          refuse(name + ": sent a message before Hello");
          return false;
        }
        hello = net::decodeHello(payload, name);
        const auto& s = sink.settings;
        if (!s.token.empty() && hello.token != s.token) {
          refuse(name + ": wrong token");
          return false;
        }
        if (!hello.wallId.empty() && hello.wallId != s.wall.id) {
          refuse(name + ": renders for wall '" + hello.wallId + "', this sink shows '" + s.wall.id +
                 "'");
          return false;
        }
        greeted = true;
        name += hello.role == net::Role::Controller ? " (controller)"
                                                    : " (rank " + std::to_string(hello.rank) + ")";
        {
          std::lock_guard lock(sink.statsMutex);
          ++sink.stats.peersAccepted;
        }
        if (hello.role == net::Role::Controller) {
          sink.controller = shared_from_this();
          std::lock_guard lock(sink.statsMutex);
          sink.stats.controllerConnected = true;
        }
        send(net::encodeMessage(net::Welcome{s.wall.id, s.wall.width, s.wall.height}));
        return true;
      }
      switch (type) {
        case MessageType::Tile:
          if (hello.role != net::Role::Renderer)
            throw FormatError(name, "a controller sent a tile");
          sink.onTile(frame, net::decodeTile(payload, name), hello.rank, name);
          return true;
        case MessageType::FrameEnd:
          net::decodeFrameEnd(payload, name);
          return true;
        case MessageType::Bye:
          close();
          return false;
        default:
          throw FormatError(name, "unexpected message type " + std::to_string(int(type)));
      }
    }

    void send(std::vector<std::byte> bytes) {
      outbox.push_back(std::move(bytes));
      if (outbox.size() == 1) writeNext();
    }

    void writeNext() {
      auto self = shared_from_this();
      asio::async_write(socket, asio::buffer(outbox.front()),
                        [self](asio::error_code ec, std::size_t) {
                          self->outbox.pop_front();
                          if (ec) return self->close();
                          if (!self->outbox.empty()) return self->writeNext();
                          if (self->closing) self->close();
                        });
    }

    // Tells the peer why (Bye) and closes once that is sent.
    void refuse(const std::string& reason) {
      {
        std::lock_guard lock(sink.statsMutex);
        ++sink.stats.peersRefused;
      }
      sink.say("sink: refused " + reason);
      closing = true;
      send(net::encodeMessage(net::Bye{reason.substr(0, net::kMaxString)}));
    }

    void drop(const std::string& why) {
      if (!why.empty()) {
        std::lock_guard lock(sink.statsMutex);
        ++sink.stats.peersDropped;
      }
      if (!why.empty()) sink.say("sink: dropped " + name + ": " + why);
      close();
    }

    void close() {
      if (greeted && hello.role == net::Role::Controller) {
        std::lock_guard lock(sink.statsMutex);
        sink.stats.controllerConnected = false;
      }
      asio::error_code ignored;
      socket.shutdown(tcp::socket::shutdown_both, ignored);
      socket.close(ignored);
      sink.sessions.erase(shared_from_this());
    }
  };

  void accept() {
    acceptor.async_accept([this](asio::error_code ec, tcp::socket socket) {
      if (ec) return;  // acceptor closed
      asio::error_code ignored;
      socket.set_option(tcp::no_delay(true), ignored);
      auto session = std::make_shared<Session>(*this, std::move(socket));
      sessions.insert(session);
      session->readHeader();
      accept();
    });
  }

  void dropFrame(std::map<std::uint64_t, PendingFrame>::iterator it, const char* why) {
    const long long total = settings.wall.displayPixels();
    char line[200];
    std::snprintf(line, sizeof line, "frame %llu dropped (%s): %.1f%% of display pixels arrived",
                  (unsigned long long)it->first, why,
                  100.0 * double(it->second.coveredDisplayPixels) / double(total));
    say(line);
    {
      std::lock_guard lock(statsMutex);
      ++stats.framesDropped;
      stopIfDone();
    }
    pending.erase(it);
  }

  void onTile(std::uint64_t frame, const net::TileMessage& tile, int rank,
              const std::string& peer) {
    const Wall& wall = settings.wall;
    const auto& r = tile.rect;
    if (r.x + r.width > wall.width || r.y + r.height > wall.height)
      throw FormatError(peer, "tile outside the " + std::to_string(wall.width) + "x" +
                                  std::to_string(wall.height) + " screen");
    if (lastComplete && frame <= *lastComplete) return;  // late: that frame is settled
    // Decode before touching the frame: a corrupt tile must not mark any pixel as arrived.
    const node::Image image = net::decodeTile(tile.bytes, tile.codec, r.width, r.height, peer);
    auto it = pending.find(frame);
    if (it == pending.end()) {
      while (int(pending.size()) >= settings.pendingFrames)
        dropFrame(pending.begin(), "too many frames open");
      it = pending.emplace(frame, PendingFrame{}).first;
      it->second.image = node::Image(wall.width, wall.height);
      it->second.covered.assign(std::size_t(wall.width) * std::size_t(wall.height), 0);
    }
    PendingFrame& f = it->second;
    for (int y = 0; y < r.height; ++y) {
      const std::size_t row = std::size_t(r.y + y) * std::size_t(wall.width) + std::size_t(r.x);
      std::memcpy(&f.image.pixels[row], &image.pixels[std::size_t(y) * std::size_t(r.width)],
                  std::size_t(r.width) * 4);
      for (int x = 0; x < r.width; ++x)
        if (!f.covered[row + std::size_t(x)]) {
          f.covered[row + std::size_t(x)] = 1;
          f.coveredDisplayPixels += displayMask[row + std::size_t(x)];
        }
    }
    f.decidedUnixMicros = f.decidedUnixMicros
                              ? std::min(f.decidedUnixMicros, tile.decidedUnixMicros)
                              : tile.decidedUnixMicros;
    f.bytes += tile.bytes.size();
    ++f.tiles;
    f.ranks.insert(rank);
    if (f.coveredDisplayPixels < wall.displayPixels()) return;
    // Complete: older frames can never be shown now.
    while (pending.begin()->first != frame) dropFrame(pending.begin(), "a newer frame completed");
    CompleteFrame done{frame, std::move(f)};
    pending.erase(pending.begin());
    lastComplete = frame;
    std::lock_guard lock(presentMutex);
    if (toPresent) {
      say("frame " + std::to_string(toPresent->frame) + " skipped: the sink fell behind");
      std::lock_guard s(statsMutex);
      ++stats.framesStale;
      stopIfDone();
    }
    toPresent = std::move(done);
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
      try {
        if (!settings.outDir.empty()) {
          char stem[64];
          std::snprintf(stem, sizeof stem, "frame_%05llu", (unsigned long long)frame.frame);
          const auto base = std::filesystem::path(settings.outDir);
          for (const auto& d : wall.displays)
            node::writeImage(frame.data.image.crop(d.rect),
                             (base / (std::string(stem) + "_" + d.name + ".png")).string());
          if (settings.mosaic)
            node::writeImage(frame.data.image,
                             (base / (std::string(stem) + "_mosaic.png")).string());
        }
      } catch (const std::exception& e) {
        say(std::string("sink: cannot write frame: ") + e.what());
      }
      const double latencyMs =
          frame.data.decidedUnixMicros
              ? double(net::unixMicrosNow() - frame.data.decidedUnixMicros) / 1e3
              : 0.0;
      {
        std::lock_guard lock(statsMutex);
        const int presented = ++stats.framesPresented;
        latencySumMs += latencyMs;
        stats.meanLatencyMs = latencySumMs / presented;
      }
      char line[256];
      std::snprintf(line, sizeof line,
                    "frame %llu presented: %zu display(s), %d tiles from %zu rank(s), %.1f KiB, "
                    "latency %.1f ms",
                    (unsigned long long)frame.frame, wall.displays.size(), frame.data.tiles,
                    frame.data.ranks.size(), double(frame.data.bytes) / 1024, latencyMs);
      say(line);
      std::lock_guard lock(statsMutex);
      stopIfDone();
    }
  }
};

Sink::Sink(SinkSettings settings, SinkLog log) : impl_(std::make_unique<Impl>()) {
  auto& s = *impl_;
  s.settings = std::move(settings);
  s.log = std::move(log);
  validateWall(s.settings.wall, "wall");
  if (s.settings.pendingFrames < 1) s.settings.pendingFrames = 1;
  const auto& wall = s.settings.wall;
  s.displayMask.assign(std::size_t(wall.width) * std::size_t(wall.height), 0);
  for (const auto& d : wall.displays)
    for (int y = d.rect.y; y < d.rect.y + d.rect.height; ++y)
      std::fill_n(s.displayMask.begin() + std::ptrdiff_t(std::size_t(y) * std::size_t(wall.width) +
                                                         std::size_t(d.rect.x)),
                  d.rect.width, std::uint8_t(1));
  if (!s.settings.outDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(s.settings.outDir, ec);
    if (ec) throw FormatError(s.settings.outDir, "cannot create: " + ec.message());
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

Sink::~Sink() {
  {
    std::lock_guard lock(impl_->presentMutex);
    impl_->presenterStop = true;
  }
  impl_->presentReady.notify_all();
  if (impl_->presenter.joinable()) impl_->presenter.join();
}

std::uint16_t Sink::port() const { return impl_->acceptor.local_endpoint().port(); }

void Sink::run() {
  impl_->accept();
  impl_->io.run();
  // Stop listening and hang up on every peer, so the port is free for a new sink at once.
  asio::error_code ignored;
  impl_->acceptor.close(ignored);
  for (const auto& session : std::set(impl_->sessions)) {
    session->socket.shutdown(tcp::socket::shutdown_both, ignored);
    session->socket.close(ignored);
  }
  impl_->sessions.clear();
  // Finish the frame being written before returning.
  {
    std::lock_guard lock(impl_->presentMutex);
    impl_->presenterStop = true;
  }
  impl_->presentReady.notify_all();
  if (impl_->presenter.joinable()) impl_->presenter.join();
}

void Sink::stop() {
  asio::post(impl_->io, [this] { impl_->io.stop(); });
}

void Sink::sendControl(const net::Control& control) {
  asio::post(impl_->io, [this, control] {
    if (auto c = impl_->controller.lock())
      c->send(net::encodeMessage(control));
    else
      impl_->say("sink: no render job connected to take the command");
  });
}

SinkStats Sink::stats() const {
  std::lock_guard lock(impl_->statsMutex);
  return impl_->stats;
}

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
