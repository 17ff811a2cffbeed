// The client side of the wall transport against a loopback peer that misbehaves.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <thread>
#include <voxwall/net/tcp.hpp>

using namespace voxwall;

namespace {

// Listens on a free loopback port; a connecting client gets a Welcome, then nobody reads.
class FrozenSink {
 public:
  FrozenSink() {
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(listener_, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
    ::listen(listener_, 1);
    socklen_t len = sizeof addr;
    ::getsockname(listener_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
    thread_ = std::thread([this] {
      peer_ = ::accept(listener_, nullptr, nullptr);
      const auto welcome = net::encodeMessage(net::Welcome{"frozen", 64, 64, {}, true});
      (void)!::send(peer_, welcome.data(), welcome.size(), MSG_NOSIGNAL);
    });
  }
  ~FrozenSink() {
    thread_.join();
    ::close(peer_);
    ::close(listener_);
  }
  std::uint16_t port() const { return port_; }

 private:
  int listener_ = -1, peer_ = -1;
  std::uint16_t port_ = 0;
  std::thread thread_;
};

}  // namespace

// A sink that stops reading must not hold a rank: the send gives up at its deadline.
TEST(Connection, SendToAPeerThatStopsReadingTimesOut) {
  FrozenSink sink;
  auto c = net::Connection::open("127.0.0.1", sink.port(), net::Hello{}, 2000);
  ASSERT_EQ(c->welcome().wallId, "frozen");
  const std::vector<std::byte> big(64u << 20);  // far more than the socket buffers hold
  const auto start = std::chrono::steady_clock::now();
  try {
    c->send(big, 300);
    FAIL() << "64 MiB went to a peer that reads nothing";
  } catch (const net::NetError& e) {
    EXPECT_NE(std::string(e.what()).find("timed out"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
}

TEST(Connection, NoSinkListeningIsAClearError) {
  int probe = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  socklen_t len = sizeof addr;
  ::getsockname(probe, reinterpret_cast<sockaddr*>(&addr), &len);
  const std::uint16_t port = ntohs(addr.sin_port);
  ::close(probe);  // a port nobody listens on
  EXPECT_THROW(net::Connection::open("127.0.0.1", port, net::Hello{}, 1000), net::NetError);
  net::TileStreamer streamer("127.0.0.1", port, net::Hello{});
  EXPECT_FALSE(streamer.sendFrame(0, {}, 0));
  EXPECT_NE(streamer.lastError().find("127.0.0.1"), std::string::npos) << streamer.lastError();
  // A frame sent in parts: no connection, so the frame is skipped, part after part.
  EXPECT_FALSE(streamer.beginFrame(1));
  EXPECT_FALSE(streamer.sendTiles({net::EncodedTile{{0, 0, 1, 1}, net::TileCodec::Raw, {}}}, 0));
  EXPECT_FALSE(streamer.endFrame());
  EXPECT_EQ(streamer.bytesSent(), 0u);
}
