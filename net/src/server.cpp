#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <deque>
#include <set>
#include <stdexcept>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/text.hpp>
#include <voxwall/net/asio.hpp>
#include <voxwall/net/fair_share.hpp>
#include <voxwall/net/server.hpp>
#include <voxwall/net/tcp.hpp>

namespace voxwall::net {

using asio::ip::tcp;

namespace {
constexpr std::size_t kPayloadChunk = 1 << 20;  // a payload's memory grows as its bytes arrive
constexpr int kMaxUngreetedPerAddress = 16;     // connections without a Hello, per address
}  // namespace

struct Server::Impl {
  struct Session;

  asio::io_context& io;
  ServerSettings settings;
  PeerHandler& handler;
  std::function<void(const std::string&)> log;
  tcp::acceptor acceptor{io};
  asio::steady_timer acceptPause{io};
  std::set<std::shared_ptr<Session>> sessions;
  std::uint64_t nextSerial = 1;
  // The sessions' payload buffers' capacities, together (the io thread writes it).
  std::atomic<std::size_t> receiving{0};

  Impl(asio::io_context& i, const ServerSettings& s, PeerHandler& h,
       std::function<void(const std::string&)> l)
      : io(i), settings(s), handler(h), log(std::move(l)) {}

  void say(const std::string& line) {
    if (log) log(line);
  }

  struct Session : Peer, std::enable_shared_from_this<Session> {
    Impl& server;
    tcp::socket socket;
    // The Hello deadline, then (once greeted) the idle deadline, checked against lastHeard.
    asio::steady_timer deadline;
    std::chrono::steady_clock::time_point lastHeard = std::chrono::steady_clock::now();
    bool watchingIdle = false;
    std::array<std::byte, kHeaderBytes> header{};
    std::vector<std::byte> payload;
    std::uint32_t payloadBytes = 0;
    MessageType type{};
    std::uint64_t frame = 0;
    bool closing = false, closed = false;
    std::deque<std::vector<std::byte>> outbox;
    std::size_t outboxBytes = 0;

    static std::string nameOf(tcp::socket& socket) {
      asio::error_code ec;
      const auto ep = socket.remote_endpoint(ec);
      return ec ? std::string("peer")
                : "peer " + ep.address().to_string() + ":" + std::to_string(ep.port());
    }

    static std::string addressOf(tcp::socket& socket) {
      asio::error_code ec;
      const auto ep = socket.remote_endpoint(ec);
      return ec ? std::string() : ep.address().to_string();
    }

    Session(Impl& s, tcp::socket sock)
        : Peer(nameOf(sock), addressOf(sock)),
          server(s),
          socket(std::move(sock)),
          deadline(s.io),
          serial(s.nextSerial++) {}
    std::uint64_t serial;  // the order it came in

    void start() {
      server.handler.attach(*this);
      auto self = shared_from_this();
      const int timeoutMs = server.settings.helloTimeoutMs;
      deadline.expires_after(std::chrono::milliseconds(timeoutMs));
      deadline.async_wait([self, timeoutMs](asio::error_code ec) {
        if (ec || self->closed || self->greeted()) return;
        self->drop("sent no Hello within " + std::to_string(timeoutMs) + " ms");
      });
      readHeader();
    }

    // A greeted peer must keep saying something (tiles, or KeepAlive when it has nothing to
    // send): one that is silent for peerIdleMs (a squatter, a hung rank) is dropped, so it
    // cannot hold the wall for its job.
    void watchIdle() {
      const auto idle = std::chrono::milliseconds(server.settings.peerIdleMs);
      const auto silent = std::chrono::steady_clock::now() - lastHeard;
      if (silent >= idle) {
        const int ms = server.settings.peerIdleMs;
        return drop("sent nothing for " + durationText(ms) + " (--peer-idle)");
      }
      auto self = shared_from_this();
      deadline.expires_after(idle - silent);
      deadline.async_wait([self](asio::error_code ec) {
        if (!ec && !self->closed) self->watchIdle();
      });
    }

    void readHeader() {
      auto self = shared_from_this();
      asio::async_read(socket, asio::buffer(header), [self](asio::error_code ec, std::size_t) {
        if (self->closed) return;
        if (ec) return self->drop(ec == asio::error::eof ? "" : ec.message());
        self->lastHeard = std::chrono::steady_clock::now();
        try {
          self->payloadBytes = checkHeader(self->header, self->name(), &self->type, &self->frame);
        } catch (const FormatError& e) {
          return self->refuse(e.what());
        }
        const std::uint32_t limit = self->server.handler.payloadLimit(*self);
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
      if (payload.capacity() < have + chunk) {
        // Grows by doubling (capped at the payload), each growth counted as it is made.
        const std::size_t before = payload.capacity();
        const std::size_t grown =
            std::max(have + chunk, std::min<std::size_t>(payloadBytes, 2 * before));
        if (server.receiving + (grown - before) > server.settings.maxReceivingBytes)
          return drop(name() + ": the messages being received from all peers reach the limit (" +
                      std::to_string(server.settings.maxReceivingBytes >> 20) +
                      " MiB); this one's is not read");
        payload.reserve(grown);
        server.receiving += payload.capacity() - before;
      }
      payload.resize(have + chunk);
      auto self = shared_from_this();
      asio::async_read(
          socket, asio::buffer(payload.data() + have, chunk),
          [self](asio::error_code ec, std::size_t) {
            if (self->closed) return;
            if (ec) return self->drop(ec == asio::error::eof ? "closed mid-message" : ec.message());
            self->lastHeard = std::chrono::steady_clock::now();
            self->readPayload();
          });
    }

    void onMessage() {
      server.handler.received(kHeaderBytes + payload.size());
      try {
        checkPayload(header, payload, name());
        if (!server.handler.handle(*this, type, frame, payload)) return;
      } catch (const FormatError& e) {
        return drop(e.what());
      }
      if (closed) return;  // the handler hung up on this peer
      // A large message's buffer is not kept for the small ones that follow (a peer sending
      // KeepAlives kept 64 MiB): between messages a peer holds at most one chunk.
      if (payload.capacity() > kPayloadChunk) letGoOfPayload();
      if (greeted() && !watchingIdle) {  // the Hello deadline gives way to the idle deadline
        watchingIdle = true;
        watchIdle();
      }
      readHeader();
    }

    std::size_t receiveBufferBytes() const override { return payload.capacity(); }

    void letGoOfPayload() {
      if (countedCapacity) server.receiving -= payload.capacity();
      std::vector<std::byte>().swap(payload);
    }
    bool countedCapacity = true;  // payload's capacity is in server.receiving (until close())

    void send(std::vector<std::byte> bytes) override {
      if (closed) return;
      // A write is in flight whenever the outbox holds bytes, and holds this session: dropping
      // it here does not destroy it under the caller.
      if (outboxBytes + bytes.size() > server.settings.maxOutboxBytes)
        return drop("has " + std::to_string(outboxBytes) +
                    " bytes waiting that it has not read (it does not read what it is sent)");
      outboxBytes += bytes.size();
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
                          self->outboxBytes -= self->outbox.front().size();
                          self->outbox.pop_front();
                          if (ec) return self->drop(ec.message());
                          if (!self->outbox.empty()) return self->writeNext();
                          if (self->closing) self->close();
                        });
    }

    void refuse(const std::string& reason) { server.handler.refuse(*this, reason); }

    void drop(const std::string& why) {
      if (closed) return;
      server.handler.dropped(*this, why);
      close();
    }

    void close() {
      if (closed) return;
      closed = true;
      // Counted as let go; freed with the session, once no read can still be writing to it.
      server.receiving -= payload.capacity();
      countedCapacity = false;
      server.handler.detach(*this);
      asio::error_code ignored;
      deadline.cancel();
      socket.shutdown(tcp::socket::shutdown_both, ignored);
      socket.close(ignored);
      server.sessions.erase(shared_from_this());
    }
  };

  // Every place is held: the oldest connection that has not said Hello, of the address holding
  // the most such, gives its place up (net::oldestOfCrowd); greeted peers keep theirs. Whether a
  // place was freed.
  bool makeRoom() {
    std::vector<std::shared_ptr<Session>> waiting;
    for (const auto& s : sessions)
      if (!s->greeted() && !s->closed) waiting.push_back(s);
    std::sort(waiting.begin(), waiting.end(),
              [](auto& a, auto& b) { return a->serial < b->serial; });
    std::vector<HeldPlace> places;
    for (const auto& s : waiting) places.push_back({-1, s->address()});
    const int victim = oldestOfCrowd(places);
    if (victim < 0) return false;
    waiting[std::size_t(victim)]->drop(
        "replaced by a newer connection: " + std::to_string(settings.maxPeers) +
        " peers connected (--max-peers) and it had not said Hello");
    return true;
  }

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
      if (int(sessions.size()) >= settings.maxPeers && !makeRoom()) {
        handler.refusedConnection(std::to_string(settings.maxPeers) +
                                  " peers connected (--max-peers)");
        socket.close(ignored);
        return accept();
      }
      // Connections that have not said Hello yet, from one address: a few (a rank says Hello at
      // once), so silent connections from one host cannot take every place from the others.
      const std::string from = Session::addressOf(socket);
      int waiting = 0;
      for (const auto& s : sessions) waiting += !s->greeted() && s->address() == from;
      if (waiting >= kMaxUngreetedPerAddress) {
        handler.refusedConnection(std::to_string(waiting) + " connections from " + from +
                                  " have not said Hello");
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
};

Server::Server(asio::io_context& io, const ServerSettings& settings, PeerHandler& handler,
               std::function<void(const std::string&)> log)
    : impl_(std::make_unique<Impl>(io, settings, handler, std::move(log))) {
  if (settings.maxPeers < 1) throw std::invalid_argument("--max-peers must be at least 1");
  if (settings.helloTimeoutMs < 1)
    throw std::invalid_argument("the Hello timeout must be positive");
  if (settings.peerIdleMs < 1) throw std::invalid_argument("--peer-idle must be positive");
  auto& acceptor = impl_->acceptor;
  asio::error_code ec;
  const auto address = asio::ip::make_address(settings.host, ec);
  if (ec) throw NetError("--listen: '" + settings.host + "' is not an IP address");
  const tcp::endpoint endpoint(address, settings.port);
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    throw NetError("cannot listen on " + settings.host + ":" + std::to_string(settings.port) +
                   ": " + ec.message());
}

Server::~Server() = default;

std::uint16_t Server::port() const { return impl_->acceptor.local_endpoint().port(); }

std::size_t Server::receivingBytes() const { return impl_->receiving.load(); }

void Server::start() { impl_->accept(); }

void Server::close() {
  asio::error_code ignored;
  impl_->acceptor.close(ignored);
  impl_->acceptPause.cancel();
  for (const auto& session : std::set(impl_->sessions)) session->close();
  impl_->sessions.clear();
}

}  // namespace voxwall::net
