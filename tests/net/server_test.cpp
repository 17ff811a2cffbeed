// The server half of the wall protocol against its own client half (tcp.hpp), with a handler
// that knows nothing of walls: the sessions' limits hold without the sink behind them.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <voxwall/net/asio.hpp>
#include <voxwall/net/fair_share.hpp>
#include <voxwall/net/server.hpp>
#include <voxwall/net/tcp.hpp>

#include "support/wait_until.hpp"

using namespace voxwall;

namespace {

// Greets every Hello with a Welcome and sends every Control back; counts what happens.
class EchoHandler : public net::PeerHandler {
 public:
  std::uint32_t limit = net::kMaxHelloPayload;

  void attach(net::Peer&) override { ++attached; }
  void detach(net::Peer&) override { ++detached; }
  std::uint32_t payloadLimit(const net::Peer&) const override { return limit; }
  bool handle(net::Peer& peer, net::MessageType type, std::uint64_t,
              std::span<const std::byte> payload) override {
    if (type == net::MessageType::Hello) {
      const auto hello = net::decodeHello(payload, peer.name());
      peer.markGreeted(hello, peer.name() + " (echo)");
      peer.send(net::encodeMessage(net::Welcome{hello.wallId, 64, 32, {}, true}));
      return true;
    }
    if (type == net::MessageType::Control) {
      peer.send(net::encodeMessage(net::decodeControl(payload, peer.name())));
      return true;
    }
    if (type == net::MessageType::Tile || type == net::MessageType::KeepAlive) {
      bufferBytes = peer.receiveBufferBytes();  // as the message is handled
      ++kept;
      return true;
    }
    return false;
  }
  void refuse(net::Peer& peer, const std::string& reason) override {
    remember(reason);
    peer.send(net::encodeMessage(net::Bye{reason}));
    peer.hangUp();
  }
  void dropped(net::Peer&, const std::string& why) override {
    ++drops;
    remember(why);
  }
  void received(std::uint64_t bytes) override { bytesReceived += bytes; }
  void refusedConnection(const std::string& why) override {
    ++connectionsRefused;
    remember(why);
  }

  std::string lastReason() {
    std::lock_guard lock(mutex_);
    return last_;
  }

  std::atomic<int> attached{0}, detached{0}, drops{0}, connectionsRefused{0};
  std::atomic<std::uint64_t> bytesReceived{0};
  std::atomic<std::size_t> bufferBytes{0};
  std::atomic<int> kept{0};  // tiles and KeepAlives handled

 private:
  void remember(const std::string& text) {
    std::lock_guard lock(mutex_);
    last_ = text;
  }
  std::mutex mutex_;
  std::string last_;
};

// A server on its own io thread, closed and joined on destruction.
class RunningServer {
 public:
  RunningServer(EchoHandler& handler, net::ServerSettings settings)
      : server_(io_, settings, handler), guard_(asio::make_work_guard(io_)) {
    server_.start();
    thread_ = std::thread([this] { io_.run(); });
  }
  ~RunningServer() {
    asio::post(io_, [this] {
      server_.close();
      guard_.reset();
    });
    thread_.join();
  }
  std::uint16_t port() const { return server_.port(); }
  std::size_t receivingBytes() const { return server_.receivingBytes(); }

 private:
  asio::io_context io_;
  net::Server server_;
  asio::executor_work_guard<asio::io_context::executor_type> guard_;
  std::thread thread_;
};

net::Hello helloFor(const std::string& wall) {
  net::Hello hello;
  hello.wallId = wall;
  return hello;
}

}  // namespace

TEST(Server, TalksToTheClientHalf) {
  EchoHandler handler;
  {
    RunningServer server(handler, {});
    auto connection = net::Connection::open("127.0.0.1", server.port(), helloFor("echo"), 5000);
    EXPECT_EQ(connection->welcome().wallId, "echo");
    EXPECT_EQ(connection->welcome().screenWidth, 64);
    connection->send(net::encodeMessage(net::Control{net::ControlCommand::Zoom, 1.5, 0}));
    const auto reply = connection->receive(5000);
    ASSERT_TRUE(reply.has_value());
    ASSERT_EQ(reply->type, net::MessageType::Control);
    EXPECT_EQ(net::decodeControl(reply->payload, "reply").a, 1.5);
    connection->close();
    EXPECT_TRUE(test::waitUntil([&] { return handler.detached.load() == 1; }));
  }
  EXPECT_EQ(handler.attached.load(), 1);
  EXPECT_GT(handler.bytesReceived.load(), 2 * net::kHeaderBytes);
}

TEST(Server, APayloadOverTheHandlersLimitIsRefusedBeforeItIsRead) {
  EchoHandler handler;
  handler.limit = 8;
  RunningServer server(handler, {});
  EXPECT_THROW(net::Connection::open("127.0.0.1", server.port(), helloFor("echo"), 5000),
               net::SinkRefused);
  EXPECT_NE(handler.lastReason().find("before its Hello (limit 8)"), std::string::npos)
      << handler.lastReason();
  EXPECT_EQ(handler.bytesReceived.load(), 0u);
}

TEST(Server, PeersOverTheCapAreRefusedAndTheFirstKeepsWorking) {
  EchoHandler handler;
  net::ServerSettings settings;
  settings.maxPeers = 1;
  RunningServer server(handler, settings);
  auto first = net::Connection::open("127.0.0.1", server.port(), helloFor("echo"), 5000);
  EXPECT_THROW(net::Connection::open("127.0.0.1", server.port(), helloFor("echo"), 2000),
               net::NetError);
  EXPECT_EQ(handler.connectionsRefused.load(), 1);
  EXPECT_NE(handler.lastReason().find("1 peers connected"), std::string::npos);
  first->send(net::encodeMessage(net::Control{net::ControlCommand::Reset, 0, 0}));
  EXPECT_TRUE(first->receive(5000).has_value());
}

TEST(Server, ASilentPeerIsDroppedAfterTheHelloTimeout) {
  EchoHandler handler;
  net::ServerSettings settings;
  settings.helloTimeoutMs = 100;
  RunningServer server(handler, settings);
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(server.port());
  ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  EXPECT_TRUE(test::waitUntil([&] { return handler.drops.load() == 1; }));
  EXPECT_EQ(handler.lastReason(), "sent no Hello within 100 ms");
  char byte;
  EXPECT_EQ(::recv(fd, &byte, 1, 0), 0);  // the server closed the connection
  ::close(fd);
}

// A greeted peer that sent one large message and then only KeepAlives held the large message's
// buffer (64 MiB a peer): it is let go, and between messages a peer holds at most a chunk.
TEST(Server, APeersBufferShrinksAfterALargeMessage) {
  EchoHandler handler;
  handler.limit = 16u << 20;
  RunningServer server(handler, {});
  auto client = net::Connection::open("127.0.0.1", server.port(), helloFor("w"), 2000);
  net::TileMessage big;
  big.rect = {0, 0, 1, 1};
  big.codec = net::TileCodec::Raw;
  big.bytes.assign(8u << 20, std::byte{7});
  client->send(net::encodeMessage(0, big));
  ASSERT_TRUE(test::waitUntil([&] { return handler.kept == 1; }));
  EXPECT_GE(handler.bufferBytes.load(), 8u << 20);  // the large message in hand
  client->send(net::encodeKeepAlive());
  ASSERT_TRUE(test::waitUntil([&] { return handler.kept == 2; }));
  EXPECT_LE(handler.bufferBytes.load(), std::size_t(1) << 20);
}

// Greeted peers each in the middle of a large message held what had arrived of it, with no bound
// across peers (16 such held 1,070 MB). Past maxReceivingBytes, together, the peer whose next
// chunk would go over is dropped; the one within keeps its message.
TEST(Server, MessagesBeingReceivedStayUnderALimitAcrossPeers) {
  EchoHandler handler;
  handler.limit = 16u << 20;
  net::ServerSettings settings;
  settings.maxReceivingBytes = 3u << 20;
  RunningServer server(handler, settings);
  auto first = net::Connection::open("127.0.0.1", server.port(), helloFor("w"), 2000);
  auto second = net::Connection::open("127.0.0.1", server.port(), helloFor("w"), 2000);
  net::TileMessage big;
  big.rect = {0, 0, 1, 1};
  big.codec = net::TileCodec::Raw;
  big.bytes.assign(5u << 19, std::byte{7});  // 2.5 MiB: three chunks' room
  const auto message = net::encodeMessage(0, big);
  const std::size_t part = message.size() - 1000;
  first->send(std::span(message).first(part));
  ASSERT_TRUE(test::waitUntil([&] { return server.receivingBytes() >= (5u << 19) - 1000; }));
  try {
    second->send(message);
  } catch (const net::NetError&) {
    // dropped while it sent: what the test waits for
  }
  ASSERT_TRUE(test::waitUntil([&] { return handler.drops == 1; }));
  EXPECT_NE(handler.lastReason().find("reach the limit (3 MiB)"), std::string::npos)
      << handler.lastReason();
  first->send(std::span(message).subspan(part));
  EXPECT_TRUE(test::waitUntil([&] { return handler.kept == 1; }));
  EXPECT_LE(server.receivingBytes(), 3u << 20);
}

// A peer that never reads what it is sent (a controller that reads no frame notes) grew the
// server's memory without bound: past maxOutboxBytes queued for it, it is dropped.
TEST(Server, APeerThatReadsNothingItIsSentIsDropped) {
  EchoHandler handler;
  net::ServerSettings settings;
  settings.maxOutboxBytes = 64u << 10;
  RunningServer server(handler, settings);
  auto client = net::Connection::open("127.0.0.1", server.port(), helloFor("w"), 2000);
  // Controls the server echoes, far more than the socket buffers hold; the client reads none.
  const auto one = net::encodeMessage(net::Control{net::ControlCommand::Rotate, 1, 2});
  std::vector<std::byte> many;
  for (int i = 0; i < 400000; ++i) many.insert(many.end(), one.begin(), one.end());
  try {
    client->send(many, 20000);
  } catch (const net::NetError&) {
    // the server hung up while the client still sent
  }
  ASSERT_TRUE(test::waitUntil([&] { return handler.drops == 1; }));
  EXPECT_NE(handler.lastReason().find("it does not read what it is sent"), std::string::npos)
      << handler.lastReason();
}

TEST(Server, SettingsThatCannotWorkAreRefused) {
  EchoHandler handler;
  asio::io_context io;
  net::ServerSettings noPeers;
  noPeers.maxPeers = 0;
  EXPECT_THROW((net::Server{io, noPeers, handler}), std::invalid_argument);
  net::ServerSettings badHost;
  badHost.host = "not-an-address";
  EXPECT_THROW((net::Server{io, badHost, handler}), net::NetError);
}

// Which place a newcomer takes when a pool is full (fair_share.hpp).
TEST(FairShare, PlacesGoToDisplaysThenToAddresses) {
  using net::HeldPlace;
  const std::vector<HeldPlace> crowded{{0, "a"}, {0, "a"}, {0, "a"}};
  EXPECT_EQ(net::fairShareVictim(crowded, 1, "b"), 0);   // another display: the oldest of 0
  EXPECT_EQ(net::fairShareVictim(crowded, 1, "a"), 0);   // through one tunnel too
  EXPECT_EQ(net::fairShareVictim(crowded, 0, "b"), 0);   // another address, same display
  EXPECT_EQ(net::fairShareVictim(crowded, 0, "a"), -1);  // the crowd itself
  const std::vector<HeldPlace> even{{0, "a"}, {1, "a"}, {0, "b"}, {1, "b"}};
  EXPECT_EQ(net::fairShareVictim(even, 0, "c"), -1);  // every display and address has its share
  EXPECT_EQ(net::fairShareVictim(even, 1, "a"), -1);
  const std::vector<HeldPlace> mixed{{1, "b"}, {0, "a"}, {1, "a"}, {1, "a"}, {1, "a"}};
  EXPECT_EQ(net::fairShareVictim(mixed, 0, "c"), 2);  // display 1's, of its crowding address
  EXPECT_EQ(net::fairShareVictim(mixed, 1, "c"), 2);  // within display 1: a holds 3, c none
  const std::vector<HeldPlace> viewers{{-1, "x"}, {-1, "y"}, {-1, "x"}, {-1, "x"}};
  EXPECT_EQ(net::fairShareVictim(viewers, -1, "y"), 0);
  EXPECT_EQ(net::fairShareVictim(viewers, -1, "z"), 0);
  EXPECT_EQ(net::fairShareVictim(viewers, -1, "x"), -1);
  EXPECT_EQ(net::fairShareVictim({}, -1, "x"), -1);
  // Pools of the unproven: always the oldest of the address holding the most.
  EXPECT_EQ(net::oldestOfCrowd(mixed), 1);  // a holds the most: its oldest
  EXPECT_EQ(net::oldestOfCrowd(viewers), 0);
  const std::vector<HeldPlace> spread{{-1, "p"}, {-1, "q"}, {-1, "r"}};
  EXPECT_EQ(net::oldestOfCrowd(spread), 0);  // one each: the oldest
  EXPECT_EQ(net::oldestOfCrowd({}), -1);
}
