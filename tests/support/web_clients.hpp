// Clients of the sink's web view for tests (link Boost::headers and nlohmann_json): one HTTP
// request, a WebSocket viewer or display page, and a rendering rank that sends whole frames.
#pragma once

#include <sys/socket.h>
#include <sys/time.h>

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <voxwall/net/tcp.hpp>
#include <voxwall/net/tile_codec.hpp>

#include "support/sink_runner.hpp"

namespace voxwall::test {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = boost::asio::ip::tcp;

inline walls::SinkSettings webSink(const std::string& token = "") {
  auto s = test::twoDisplaySink();
  s.httpHost = "127.0.0.1";
  s.token = token;
  return s;
}

// One HTTP request; returns the status (0 when the server closed without answering) and body.
inline std::pair<int, std::string> get(std::uint16_t port, const std::string& target,
                                       http::verb verb = http::verb::get,
                                       std::size_t headerBytes = 0, const std::string& host = "") {
  boost::asio::io_context io;
  beast::tcp_stream stream(io);
  stream.connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
  http::request<http::empty_body> req(verb, target, 11);
  req.set(http::field::host, host.empty() ? "127.0.0.1:" + std::to_string(port) : host);
  if (headerBytes) req.set("X-Padding", std::string(headerBytes, 'a'));
  beast::error_code ec;
  http::write(stream, req, ec);
  beast::flat_buffer buffer;
  http::response<http::string_body> res;
  http::read(stream, buffer, res, ec);
  if (ec) return {0, ""};
  return {int(res.result_int()), res.body()};
}

// A WebSocket viewer. `origin` empty: no Origin header (not a browser).
class Viewer {
 public:
  // `from`: the local address to connect from (127.0.0.2 is another loopback client).
  Viewer(std::uint16_t port, const std::string& origin = "", const std::string& target = "/ws",
         const std::string& from = "")
      : ws_(io_) {
    auto& socket = beast::get_lowest_layer(ws_).socket();
    if (!from.empty()) {
      socket.open(tcp::v4());
      socket.bind(tcp::endpoint(boost::asio::ip::make_address(from), 0));
    }
    socket.connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
    // Blocking reads give up after 10 s instead of hanging the test.
    timeval limit{10, 0};
    ::setsockopt(socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &limit, sizeof limit);
    ws_.set_option(websocket::stream_base::decorator([origin](websocket::request_type& req) {
      if (!origin.empty()) req.set(http::field::origin, origin);
    }));
    ws_.handshake("127.0.0.1:" + std::to_string(port), target, ec_);
  }
  bool open() const { return !ec_; }
  void send(const std::string& text) {
    ws_.text(true);
    ws_.write(boost::asio::buffer(text), ec_);
  }
  // A WebSocket ping (what a viewer that reads nothing may still send).
  void ping() { ws_.ping({}, ec_); }
  void sendBinary(const std::string& bytes) {
    ws_.binary(true);
    ws_.write(boost::asio::buffer(bytes), ec_);
  }
  // The next message (empty with ec set when the connection closed or 10 s passed).
  std::string read(bool* binary = nullptr) {
    beast::flat_buffer buffer;
    ws_.read(buffer, ec_);
    if (ec_) return "";
    if (binary) *binary = ws_.got_binary();
    return beast::buffers_to_string(buffer.data());
  }
  // Reads until a binary frame message arrives; returns its JSON, and the JPEG in `jpeg`. Then
  // says "next", as the page does, unless `next` is false (the sink sends a viewer a frame only
  // once it took the last one).
  nlohmann::json readFrame(std::string* jpeg = nullptr, bool next = true) {
    for (int i = 0; i < 50; ++i) {
      bool binary = false;
      const auto m = read(&binary);
      if (ec_) return nullptr;
      if (!binary) continue;
      std::uint32_t n = 0;
      std::memcpy(&n, m.data(), 4);
      if (jpeg) *jpeg = m.substr(4 + n);
      if (next) send("next");
      return nlohmann::json::parse(m.substr(4, n));
    }
    return nullptr;
  }
  // Whether the server closed the connection (reads until it does, at most 10 s). Which error
  // says so depends on timing (a close frame, EOF, a reset, or a write that found the socket
  // gone); only a read that timed out means the connection is still open.
  bool closedByServer() {
    for (int i = 0; i < 50 && !ec_; ++i) read();
    return ec_ && ec_ != boost::asio::error::would_block && ec_ != boost::asio::error::try_again &&
           ec_ != boost::asio::error::timed_out;
  }
  std::string closeReason() const { return std::string(ws_.reason().reason.c_str()); }
  const beast::error_code& error() const { return ec_; }

 private:
  boost::asio::io_context io_;
  websocket::stream<beast::tcp_stream> ws_;
  beast::error_code ec_;
};

// A rendering rank: sends one frame of a `width` x `height` wall as two halves, at `step`;
// `noise`: pixels JPEG cannot shrink (large viewer frames).
class Renderer {
 public:
  Renderer(std::uint16_t port, std::string wallId = "t2x1", int width = 44, int height = 10)
      : c_(net::Connection::open("127.0.0.1", port,
                                 net::Hello{net::Role::Renderer, 0, 1, wallId, ""}, 2000)),
        width_(width),
        height_(height) {}
  void frame(std::uint64_t id, int step = 1, bool noise = false) {
    const int w = net::reducedSide(width_, step), h = net::reducedSide(height_, step);
    const int half = w / 2;
    std::uint32_t seed = std::uint32_t(id) * 2654435761u + 1;
    for (auto [rect, colour] : {std::pair{voxwall::Rect{0, 0, half, h}, 0x0000ffu},
                                std::pair{voxwall::Rect{half, 0, w - half, h}, 0x00ff00u}}) {
      voxwall::Image image(rect.width, rect.height);
      for (int y = 0; y < rect.height; ++y)
        for (int x = 0; x < rect.width; ++x) {
          seed = seed * 1664525u + 1013904223u;
          image.at(x, y) =
              0xff000000u | (noise ? seed >> 8 : colour | std::uint32_t((rect.x + x) * 4) << 16);
        }
      net::TileCodecSettings s;
      s.codec = net::TileCodec::Raw;
      s.segmentPixels = 4096;
      for (const auto& t : net::encodeTiles(image, rect, {0, 0, 0}, s))
        c_->send(net::encodeMessage(
            id, net::TileMessage{t.rect, t.codec, 0, t.bytes, step, 1500,
                                 step > 1 ? net::FramePhase::Interactive : net::FramePhase::Full}));
    }
  }

 private:
  std::unique_ptr<net::Connection> c_;
  int width_, height_;
};

}  // namespace voxwall::test
