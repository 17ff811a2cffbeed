#include <algorithm>
#include <tuple>
#include <utility>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/asio.hpp>
#include <voxwall/net/tcp.hpp>

namespace voxwall::net {

using asio::ip::tcp;
using Clock = std::chrono::steady_clock;

std::uint64_t unixMicrosNow() {
  return std::uint64_t(std::chrono::duration_cast<std::chrono::microseconds>(
                           std::chrono::system_clock::now().time_since_epoch())
                           .count());
}

std::pair<std::string, std::uint16_t> parseEndpoint(const std::string& text,
                                                    const std::string& option) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size())
    throw std::invalid_argument(option + ": expected HOST:PORT, got '" + text + "'");
  const std::string port = text.substr(colon + 1);
  if (port.find_first_not_of("0123456789") != std::string::npos || port.size() > 5 ||
      std::stoul(port) > 65535)
    throw std::invalid_argument(option + ": '" + port + "' is not a port number");
  std::string host = text.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  return {host, std::uint16_t(std::stoul(port))};
}

struct Connection::Impl {
  asio::io_context io;
  tcp::socket socket{io};
  MessageReader reader;
  explicit Impl(std::string source) : reader(std::move(source)) {}

  // Runs the io_context until `done` or the deadline; cancels what is pending on a timeout.
  bool runUntil(const bool& done, Clock::time_point deadline) {
    io.restart();
    while (!done && Clock::now() < deadline) {
      io.run_one_for(deadline - Clock::now());
      if (io.stopped()) io.restart();
    }
    if (done) return true;
    // Cancel, and let the cancelled handler run now: it refers to the caller's locals.
    asio::error_code ignored;
    socket.cancel(ignored);
    while (!done) {
      io.restart();
      io.run_one();
    }
    return false;
  }
};

Connection::Connection(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Connection::~Connection() { close(); }

void Connection::close() {
  if (!impl_) return;
  asio::error_code ignored;
  impl_->socket.shutdown(tcp::socket::shutdown_both, ignored);
  impl_->socket.close(ignored);
}

std::unique_ptr<Connection> Connection::open(const std::string& host, std::uint16_t port,
                                             const Hello& hello, int timeoutMs) {
  const std::string name = host + ":" + std::to_string(port);
  auto impl = std::make_unique<Impl>("sink " + name);
  const auto deadline = Clock::now() + std::chrono::milliseconds(timeoutMs);
  asio::error_code ec;
  tcp::resolver resolver(impl->io);
  const auto endpoints = resolver.resolve(host, std::to_string(port), ec);
  if (ec) throw NetError(name + ": " + ec.message());
  bool done = false;
  asio::async_connect(impl->socket, endpoints,
                      [&](const asio::error_code& e, const tcp::endpoint&) {
                        ec = e;
                        done = true;
                      });
  if (!impl->runUntil(done, deadline)) throw NetError(name + ": connection timed out");
  if (ec) throw NetError(name + ": " + ec.message());
  impl->socket.set_option(tcp::no_delay(true), ec);
  std::unique_ptr<Connection> c(new Connection(std::move(impl)));
  c->name_ = name;
  c->send(encodeMessage(hello));
  const int left = int(std::max<long long>(
      1, std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count()));
  std::optional<Message> reply;
  try {
    reply = c->receive(left);
  } catch (const NetError& e) {
    // A sink of another protocol version answers with a Bye this program cannot read.
    if (std::string(e.what()).find("protocol version") != std::string::npos)
      throw SinkRefused(e.what());
    throw;
  }
  if (!reply) throw NetError(name + ": no answer to Hello");
  if (reply->type == MessageType::Bye)
    throw SinkRefused(name + ": refused: " + decodeBye(reply->payload, name).reason);
  if (reply->type != MessageType::Welcome) throw NetError(name + ": unexpected answer to Hello");
  c->welcome_ = decodeWelcome(reply->payload, name);
  return c;
}

void Connection::send(std::span<const std::byte> bytes, int timeoutMs) {
  // A sink that stops reading (frozen, not dead) must not hold a rank forever: give up after the
  // deadline, as if the connection had dropped.
  asio::error_code ec;
  bool done = false;
  asio::async_write(impl_->socket, asio::buffer(bytes.data(), bytes.size()),
                    [&](const asio::error_code& e, std::size_t) { ec = e, done = true; });
  if (!impl_->runUntil(done, Clock::now() + std::chrono::milliseconds(timeoutMs)))
    throw NetError(name_ + ": sending timed out after " + std::to_string(timeoutMs) + " ms");
  if (ec) throw NetError(name_ + ": " + ec.message());
}

std::optional<Message> Connection::receive(int timeoutMs) {
  const auto deadline = Clock::now() + std::chrono::milliseconds(timeoutMs);
  for (;;) {
    try {
      if (auto m = impl_->reader.next()) return m;
    } catch (const FormatError& e) {
      throw NetError(e.what());
    }
    std::array<std::byte, 65536> buffer;
    std::size_t got = 0;
    asio::error_code ec;
    bool done = false;
    impl_->socket.async_read_some(
        asio::buffer(buffer),
        [&](const asio::error_code& e, std::size_t n) { ec = e, got = n, done = true; });
    if (!impl_->runUntil(done, deadline)) return std::nullopt;
    if (ec) throw NetError(name_ + ": " + (ec == asio::error::eof ? "closed" : ec.message()));
    impl_->reader.feed(std::span(buffer.data(), got));
  }
}

TileStreamer::TileStreamer(std::string host, std::uint16_t port, Hello hello, int timeoutMs,
                           int keepAliveMs)
    : host_(std::move(host)),
      port_(port),
      hello_(std::move(hello)),
      connectTimeoutMs_(timeoutMs),
      keepAliveMs_(keepAliveMs) {
  if (keepAliveMs_ > 0) keeper_ = std::thread([this] { keepAlive(); });
}

TileStreamer::~TileStreamer() {
  {
    std::lock_guard lock(mutex_);
    stopKeeper_ = true;
  }
  wake_.notify_all();
  if (keeper_.joinable()) keeper_.join();
}

void TileStreamer::keepAlive() {
  const auto interval = std::chrono::milliseconds(keepAliveMs_);
  std::unique_lock lock(mutex_);
  while (!stopKeeper_) {
    if (!connection_) {
      wake_.wait_for(lock, interval);
      continue;
    }
    if (Clock::now() < lastSent_ + interval) {
      wake_.wait_until(lock, lastSent_ + interval);
      continue;
    }
    try {
      connection_->send(encodeKeepAlive());
      lastSent_ = Clock::now();
    } catch (const NetError& e) {
      keeperError_ = e.what();
      connection_.reset();
    }
  }
}

void TileStreamer::send(std::span<const std::byte> bytes) {
  std::lock_guard lock(mutex_);
  if (!connection_)
    throw NetError(keeperError_.empty() ? host_ + ":" + std::to_string(port_) + ": not connected"
                                        : keeperError_);
  connection_->send(bytes);
  lastSent_ = Clock::now();
}

void TileStreamer::setJob(std::uint64_t jobId) {
  if (hello_.jobId == jobId) return;
  hello_.jobId = jobId;
  sending_ = false;
  std::lock_guard lock(mutex_);
  connection_.reset();
}

bool TileStreamer::ensureConnected() {
  {
    std::lock_guard lock(mutex_);
    if (connection_) return true;
  }
  if (!refused_.empty()) return false;
  const auto now = clock_();
  if (now < nextAttempt_) return false;
  ++connectAttempts_;
  try {
    auto connection = Connection::open(host_, port_, hello_, connectTimeoutMs_);
    if (const std::string why = screenMismatch(connection->welcome()); !why.empty()) {
      lastError_ = refused_ = connection->name() + ": " + why;
      return false;  // the connection closes: the sink sees the peer leave
    }
    cut_ = connection->welcome().cut();
    backoff_ = std::chrono::milliseconds(100);
    {
      std::lock_guard lock(mutex_);
      connection_ = std::move(connection);
      lastSent_ = Clock::now();
      keeperError_.clear();
    }
    wake_.notify_all();
    return true;
  } catch (const SinkRefused& e) {
    lastError_ = refused_ = e.what();
    return false;
  } catch (const NetError& e) {
    lastError_ = e.what();
    nextAttempt_ = now + backoff_;
    backoff_ = std::min(backoff_ * 2, std::chrono::milliseconds(5000));
    return false;
  }
}

void TileStreamer::expectScreen(int width, int height, std::vector<voxwall::Rect> displays) {
  expectWidth_ = width, expectHeight_ = height;
  expectDisplays_ = std::move(displays);
}

std::string TileStreamer::screenMismatch(const Welcome& welcome) const {
  if (expectWidth_ <= 0) return "";
  const auto size = [](int w, int h) { return std::to_string(w) + "x" + std::to_string(h); };
  if (welcome.screenWidth != expectWidth_ || welcome.screenHeight != expectHeight_)
    return "the sink's wall " + welcome.wallId + " is a " +
           size(welcome.screenWidth, welcome.screenHeight) + " screen where this job renders " +
           size(expectWidth_, expectHeight_) + " (not the same wall file?)";
  if (expectDisplays_.empty()) return "";
  const auto sorted = [](std::vector<voxwall::Rect> rects) {
    std::sort(rects.begin(), rects.end(), [](const voxwall::Rect& a, const voxwall::Rect& b) {
      return std::tie(a.y, a.x, a.width, a.height) < std::tie(b.y, b.x, b.width, b.height);
    });
    return rects;
  };
  const auto theirs = sorted(welcome.displays), ours = sorted(expectDisplays_);
  if (theirs.size() != ours.size())
    return "the sink's wall " + welcome.wallId + " has " + std::to_string(theirs.size()) +
           " displays where this job's has " + std::to_string(ours.size()) +
           " (not the same wall file?)";
  for (std::size_t i = 0; i < ours.size(); ++i)
    if (theirs[i].x != ours[i].x || theirs[i].y != ours[i].y || theirs[i].width != ours[i].width ||
        theirs[i].height != ours[i].height)
      return "the sink's wall " + welcome.wallId + " has a display at " +
             std::to_string(theirs[i].x) + "," + std::to_string(theirs[i].y) + " of " +
             size(theirs[i].width, theirs[i].height) + " where this job's has one at " +
             std::to_string(ours[i].x) + "," + std::to_string(ours[i].y) + " of " +
             size(ours[i].width, ours[i].height) + " (not the same wall file?)";
  return "";
}

bool TileStreamer::beginFrame(std::uint64_t frame) {
  sending_ = false;
  hello_.nextFrame = frame;
  if (!ensureConnected()) {
    if (lastError_.empty()) lastError_ = "waiting to reconnect";
    return false;
  }
  lastError_.clear();
  sending_ = true;
  frame_ = frame;
  tilesSent_ = 0;
  return true;
}

bool TileStreamer::sendTiles(const std::vector<EncodedTile>& tiles, std::uint64_t decidedUnixMicros,
                             int step, std::uint32_t renderMicros, FramePhase phase) {
  if (!sending_) return false;
  try {
    for (const auto& t : tiles) {
      const auto bytes = encodeMessage(frame_, TileMessage{t.rect, t.codec, decidedUnixMicros,
                                                           t.bytes, step, renderMicros, phase});
      send(bytes);
      bytesSent_ += bytes.size();
      ++tilesSent_;
    }
    return true;
  } catch (const NetError& e) {
    lost(e);
    return false;
  }
}

bool TileStreamer::endFrame(bool abandoned) {
  if (!sending_) return false;
  try {
    send(encodeMessage(frame_, FrameEnd{hello_.rank, tilesSent_, abandoned}));
    sending_ = false;
    return true;
  } catch (const NetError& e) {
    lost(e);
    return false;
  }
}

bool TileStreamer::abandon(std::uint64_t frame) {
  if (sending_) return false;
  {
    std::lock_guard lock(mutex_);
    if (!connection_) return false;
  }
  try {
    send(encodeMessage(frame, FrameEnd{hello_.rank, 0, true}));
    return true;
  } catch (const NetError& e) {
    lost(e);
    return false;
  }
}

void TileStreamer::lost(const NetError& e) {
  lastError_ = e.what();
  sending_ = false;
  {
    std::lock_guard lock(mutex_);
    connection_.reset();
  }
  nextAttempt_ = clock_() + backoff_;
}

bool TileStreamer::sendFrame(std::uint64_t frame, const std::vector<EncodedTile>& tiles,
                             std::uint64_t decidedUnixMicros, int step,
                             std::uint32_t renderMicros) {
  return beginFrame(frame) && sendTiles(tiles, decidedUnixMicros, step, renderMicros) && endFrame();
}

ControlChannel::ControlChannel(std::string host, std::uint16_t port, Hello hello, int keepAliveMs)
    : host_(std::move(host)), port_(port), hello_(std::move(hello)), keepAliveMs_(keepAliveMs) {
  hello_.role = Role::Controller;
  thread_ = std::thread([this] { run(); });
}

ControlChannel::~ControlChannel() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

std::vector<std::string> ControlChannel::drainNotes() {
  std::lock_guard lock(mutex_);
  return std::exchange(notes_, {});
}

std::uint64_t ControlChannel::framesPresented() const {
  std::lock_guard lock(mutex_);
  return presented_;
}

void ControlChannel::setNextFrame(std::uint64_t frame) {
  std::lock_guard lock(mutex_);
  hello_.nextFrame = frame;
}

void ControlChannel::setPlayback(std::uint64_t frame, const Playback& playback) {
  std::lock_guard lock(mutex_);
  if (playback_ == playback) return;
  playback_ = playback, playbackFrame_ = frame;
  ++playbackVersion_;
}

std::string ControlChannel::refused() const {
  std::lock_guard lock(mutex_);
  return refused_;
}

std::size_t ControlChannel::pending() const {
  std::lock_guard lock(mutex_);
  return queue_.size();
}

std::vector<Control> ControlChannel::drain() {
  std::lock_guard lock(mutex_);
  std::vector<Control> out(queue_.begin(), queue_.end());
  queue_.clear();
  return out;
}

bool ControlChannel::waitForPresented(std::uint64_t frames, std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  wake_.wait_for(lock, wait, [&] { return stop_ || presented_ > 0 || noted_ >= frames; });
  return presented_ > 0;
}

bool ControlChannel::stopsWithin(std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  return wake_.wait_for(lock, wait, [&] { return stop_; });
}

bool ControlChannel::serve(Connection& c) {
  auto lastSent = Clock::now();
  std::uint64_t playbackSent = 0;  // a new connection is told the playback again
  while (!stopsWithin(std::chrono::milliseconds(0))) {
    std::optional<std::vector<std::byte>> playback;
    {
      std::lock_guard lock(mutex_);
      if (playback_ && playbackVersion_ != playbackSent) {
        playback = encodeMessage(playbackFrame_, *playback_);
        playbackSent = playbackVersion_;
      }
    }
    if (playback) {
      c.send(*playback);
      lastSent = Clock::now();
    }
    if (keepAliveMs_ > 0 && Clock::now() - lastSent >= std::chrono::milliseconds(keepAliveMs_)) {
      c.send(encodeKeepAlive());
      lastSent = Clock::now();
    }
    const auto m = c.receive(100);
    if (!m) continue;
    if (m->type == MessageType::Control) {
      const auto control = decodeControl(m->payload, c.name());
      std::lock_guard lock(mutex_);
      queue_.push_back(control);
    } else if (m->type == MessageType::FrameNote) {
      const auto note = decodeFrameNote(m->payload, c.name());
      {
        std::lock_guard lock(mutex_);
        ++noted_;
        if (note.status == FrameStatus::Presented)
          ++presented_;
        else if (notes_.size() < 1024)
          notes_.push_back("sink: " + describe(m->frame, note));
      }
      wake_.notify_all();
    } else if (m->type == MessageType::Bye) {
      // A Bye after the job was accepted: the sink ended it (another job took the wall).
      const auto bye = decodeBye(m->payload, c.name());
      std::lock_guard lock(mutex_);
      refused_ = c.name() + ": " + bye.reason;
      return false;
    }
  }
  c.send(encodeMessage(Bye{"render job finished"}));
  return true;
}

void ControlChannel::run() {
  auto backoff = std::chrono::milliseconds(100);
  while (!stopsWithin(std::chrono::milliseconds(0))) {
    std::unique_ptr<Connection> c;
    Hello hello;
    {
      std::lock_guard lock(mutex_);
      hello = hello_;
    }
    try {
      c = Connection::open(host_, port_, hello, 1000);
    } catch (const SinkRefused& e) {
      std::lock_guard lock(mutex_);
      refused_ = e.what();
      return;
    } catch (const NetError&) {
      if (stopsWithin(backoff)) return;
      backoff = std::min(backoff * 2, std::chrono::milliseconds(5000));
      continue;
    }
    backoff = std::chrono::milliseconds(100);
    try {
      if (!serve(*c)) return;
    } catch (const std::exception&) {
      // The sink went away or sent garbage: reconnect.
    }
  }
}

}  // namespace voxwall::net
