// The server half of the wall protocol (the client half is tcp.hpp): a TCP listener on an Asio
// io_context that accepts peers, reads each message (header, then the payload in chunks as it
// arrives, both checked by wire.hpp) and hands it to a PeerHandler, which holds the protocol's
// meaning (the sink's SinkCore). Hostile peers: connections are capped (maxPeers; at most 16 from
// one address before they said Hello, so silent connections from one host leave room for the
// ranks of others), a peer without
// a Hello is dropped after helloTimeoutMs, a greeted peer that sends nothing for peerIdleMs is
// dropped (peers send KeepAlive while they have nothing else to say), a payload longer than the
// handler allows is refused before it is read, and running out of file descriptors pauses
// accepting instead of ending it. Render hosts that vanish are also found by TCP keep-alive.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>
#include <voxwall/net/wire.hpp>

namespace asio {
class io_context;
}

namespace voxwall::net {

// One connection as a protocol handler sees it. The server implements send and hangUp; tests
// and fuzz targets implement them over memory.
class Peer {
 public:
  explicit Peer(std::string name, std::string address = "")
      : name_(std::move(name)), address_(std::move(address)) {}
  virtual ~Peer() = default;
  // Queues a whole message to the peer.
  virtual void send(std::vector<std::byte> bytes) = 0;
  // Closes the connection once what is queued was sent.
  virtual void hangUp() = 0;
  const std::string& name() const { return name_; }
  // The remote address without its port ("127.0.0.1"; empty for peers that are not sockets).
  const std::string& address() const { return address_; }
  // Whether the handler accepted this peer's Hello (the server's Hello deadline ends then).
  bool greeted() const { return greeted_; }
  const Hello& hello() const { return hello_; }
  // The memory held to receive this peer's messages (its payload buffer's capacity).
  virtual std::size_t receiveBufferBytes() const { return 0; }
  // The handler accepted `hello`; `name` says who the peer is now (e.g. "... (rank 3)").
  void markGreeted(const Hello& hello, std::string name) {
    greeted_ = true;
    hello_ = hello;
    name_ = std::move(name);
  }

 private:
  std::string name_;
  std::string address_;
  bool greeted_ = false;
  Hello hello_;
};

// What a server does with its peers. Called on the io_context's thread only.
class PeerHandler {
 public:
  virtual ~PeerHandler() = default;
  // A connection was accepted / is gone (closed, dropped or refused).
  virtual void attach(Peer& peer) = 0;
  virtual void detach(Peer& peer) = 0;
  // The largest payload `peer` may send now.
  virtual std::uint32_t payloadLimit(const Peer& peer) const = 0;
  // One message whose header and payload were checked. False ends the session; throws
  // FormatError for a peer that broke the protocol (the server drops it).
  virtual bool handle(Peer& peer, MessageType type, std::uint64_t frame,
                      std::span<const std::byte> payload) = 0;
  // The server refuses `peer` (a bad header, a payload over the limit): tell it why, hang up.
  virtual void refuse(Peer& peer, const std::string& reason) = 0;
  // The server drops `peer` for `why` (empty: it simply closed).
  virtual void dropped(Peer& peer, const std::string& why) = 0;
  // A whole message of `bytes` bytes (header included) arrived.
  virtual void received(std::uint64_t bytes) = 0;
  // A connection was refused before it became a peer (maxPeers reached); `why` says so.
  virtual void refusedConnection(const std::string& why) = 0;
};

struct ServerSettings {
  std::string host = "127.0.0.1";
  std::uint16_t port = 0;     // 0: any free port (see Server::port)
  int maxPeers = 256;         // connections at once; more are refused
  int helloTimeoutMs = 5000;  // a peer the handler has not greeted by then is dropped
  int peerIdleMs = 30000;     // a greeted peer that sends no byte for this long is dropped
  // Bytes queued for a peer that does not read them (a controller's frame notes, replies): past
  // this the peer is dropped, so no peer can grow the server's memory by not reading.
  std::size_t maxOutboxBytes = std::size_t(8) << 20;
  // Bytes of messages being received, all peers together (a payload's memory grows as its bytes
  // arrive; between messages a peer keeps at most one chunk of 1 MiB): a peer whose next chunk
  // would go past this is dropped, so greeted peers mid-message cannot grow the server past it.
  std::size_t maxReceivingBytes = std::size_t(1) << 30;
};

class Server {
 public:
  // Binds and listens. Throws NetError when it cannot, std::invalid_argument for settings that
  // cannot work. `log` gets one line per transport event (accept failures, refusals).
  Server(asio::io_context& io, const ServerSettings& settings, PeerHandler& handler,
         std::function<void(const std::string&)> log = {});
  ~Server();
  std::uint16_t port() const;
  // The bytes of messages being received (ServerSettings::maxReceivingBytes); any thread.
  std::size_t receivingBytes() const;
  // Starts accepting peers on the io_context.
  void start();
  // Stops listening and hangs up on every peer at once (frees the port for a new server).
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace voxwall::net
