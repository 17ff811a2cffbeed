// Hostile peers for the sink, on loopback only: hostile_peers PORT SECONDS. Until SECONDS have
// passed (or SIGTERM), it cycles through connections that send garbage, a header claiming 64 MiB
// before any Hello, half a header and silence, a wrong protocol version, a wrong token, a Hello of
// another job, a Hello and then oversized or overflowing tiles, and it keeps up to 40 idle
// connections open. Prints how many connections of each kind it made. Exits 0 unless it could not
// connect at all (the sink died).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>
#include <xxhash.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <map>
#include <string>
#include <thread>
#include <voxwall/net/wire.hpp>

using namespace voxwall;

namespace {

volatile std::sig_atomic_t stopRequested = 0;
void requestStop(int) { stopRequested = 1; }

int connectTo(std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return -1;
  }
  timeval timeout{0, 200000};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  return fd;
}

void sendAll(int fd, const std::vector<std::byte>& bytes) {
  (void)!::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
}

// Re-seals a header after a field was changed, so the change is what the sink sees.
void reseal(std::vector<std::byte>& m) {
  const std::uint32_t h = XXH32(m.data(), 28, 0);
  std::memcpy(m.data() + 28, &h, 4);
}

void drain(int fd) {
  std::byte buf[4096];
  while (::recv(fd, buf, sizeof buf, 0) > 0) {
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: hostile_peers PORT SECONDS\n");
    return 2;
  }
  const auto port = std::uint16_t(std::atoi(argv[1]));
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(std::atoi(argv[2]));
  std::map<std::string, int> made;
  std::deque<int> idle;
  int failedConnects = 0;
  net::Hello other{net::Role::Renderer, 0, 1, "", ""};
  other.jobId = 0x0bad0bad0bad0badull;
  std::signal(SIGTERM, requestStop);
  for (int round = 0; !stopRequested && std::chrono::steady_clock::now() < end; ++round) {
    const int fd = connectTo(port);
    if (fd < 0) {
      ++failedConnects;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    std::string kind;
    switch (round % 9) {
      case 0: {
        kind = "garbage";
        std::vector<std::byte> g(4096);
        for (std::size_t i = 0; i < g.size(); ++i) g[i] = std::byte((i * 131 + round) & 255);
        sendAll(fd, g);
        break;
      }
      case 1: {
        kind = "64 MiB claimed before Hello";
        auto m = net::encodeMessage(other);
        const std::uint32_t claimed = net::kMaxPayload;
        std::memcpy(m.data() + 12, &claimed, 4);
        reseal(m);
        m.resize(net::kHeaderBytes);
        sendAll(fd, m);
        break;
      }
      case 2: {
        kind = "half a header";
        auto m = net::encodeMessage(other);
        m.resize(net::kHeaderBytes / 2);
        sendAll(fd, m);
        break;
      }
      case 3: {
        kind = "protocol version + 1";
        auto m = net::encodeMessage(other);
        const std::uint16_t v = net::kWireVersion + 1;
        std::memcpy(m.data() + 4, &v, 2);
        reseal(m);
        sendAll(fd, m);
        break;
      }
      case 4: {
        kind = "another job's Hello";
        sendAll(fd, net::encodeMessage(other));
        break;
      }
      case 5: {
        kind = "Hello, then a tile at x = 2^31 - 50";
        sendAll(fd, net::encodeMessage(other));
        net::TileMessage t;
        t.rect = {2147483647 - 50, 0, 100, 10};
        t.codec = net::TileCodec::Raw;
        t.bytes.resize(4000);
        sendAll(fd, net::encodeMessage(~std::uint64_t(0), t));
        break;
      }
      case 6: {
        kind = "payload cut off";
        net::TileMessage t;
        t.rect = {0, 0, 10, 10};
        t.codec = net::TileCodec::Raw;
        t.bytes.resize(400);
        auto m = net::encodeMessage(3, t);
        m.resize(m.size() / 2);
        sendAll(fd, m);
        break;
      }
      case 7: {
        kind = "Hello with a 60000-byte string";
        auto m = net::encodeMessage(other);
        const std::uint16_t n = 60000;
        std::memcpy(m.data() + net::kHeaderBytes + 25, &n, 2);
        sendAll(fd, m);
        break;
      }
      default: {
        kind = "idle (no Hello)";
        idle.push_back(fd);
        if (idle.size() > 40) {
          ::close(idle.front());
          idle.pop_front();
        }
        ++made[kind];
        continue;
      }
    }
    ++made[kind];
    drain(fd);
    ::close(fd);
  }
  for (const int fd : idle) ::close(fd);
  int total = 0;
  for (const auto& [kind, count] : made) {
    std::printf("hostile: %6d x %s\n", count, kind.c_str());
    total += count;
  }
  std::printf("hostile: %d connections, %d refused at connect\n", total, failedConnects);
  return total > 0 ? 0 : 1;
}
