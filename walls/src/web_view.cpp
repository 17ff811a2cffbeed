// The browser view of the wall (web_view.hpp): Boost.Beast over Boost.Asio, on a thread and an
// io_context of its own. This file must not include the standalone Asio the tile server uses.
// First: Boost 1.74's Asio uses std::exchange without including <utility>.
// clang-format off
#include <utility>
// clang-format on
#include <algorithm>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstring>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/walls/sink_core.hpp>
#include <voxwall/walls/web_view.hpp>

namespace voxwall::walls {

namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace bnet = boost::asio;
using tcp = bnet::ip::tcp;
using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxRequestHeader = 8192;
constexpr auto kRequestTimeout = std::chrono::seconds(10);
constexpr std::size_t kMaxQueuedText = 32;  // a viewer with more unsent notes is closed
constexpr std::size_t kMaxRequests = 256;   // HTTP requests being read or answered at once

std::string peerName(const tcp::socket& socket) {
  boost::system::error_code ec;
  const auto ep = socket.remote_endpoint(ec);
  if (ec) return "viewer";
  return "viewer " + ep.address().to_string() + ":" + std::to_string(ep.port());
}

// A whole-factor box filter: the frame scaled down to at most maxWidth pixels across.
voxwall::Image scaleDown(const voxwall::Image& in, int maxWidth) {
  const int k = std::max(1, (in.width + maxWidth - 1) / maxWidth);
  if (k == 1) return in;
  const int w = std::max(1, in.width / k), h = std::max(1, in.height / k);
  voxwall::Image out(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint32_t sum[4] = {0, 0, 0, 0};
      for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
          const std::uint32_t p = in.at(x * k + i, y * k + j);
          for (int c = 0; c < 4; ++c) sum[c] += (p >> (8 * c)) & 0xff;
        }
      std::uint32_t q = 0;
      for (int c = 0; c < 4; ++c)
        q |= ((sum[c] + std::uint32_t(k * k) / 2) / std::uint32_t(k * k)) << (8 * c);
      out.at(x, y) = q;
    }
  return out;
}

// A rank's tiles arrive in JPEG segments (at most 1024 pixels a side): joins the segments of one
// rank that share an edge whole, so the overlay shows the rectangles the balancer cut.
std::vector<TilePlacement> mergePlacements(std::vector<TilePlacement> tiles) {
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < tiles.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < tiles.size() && !merged; ++j) {
        auto &a = tiles[i].rect, &b = tiles[j].rect;
        if (tiles[i].rank != tiles[j].rank) continue;
        if (a.x == b.x && a.width == b.width && (a.y + a.height == b.y || b.y + b.height == a.y)) {
          a = {a.x, std::min(a.y, b.y), a.width, a.height + b.height};
          merged = true;
        } else if (a.y == b.y && a.height == b.height &&
                   (a.x + a.width == b.x || b.x + b.width == a.x)) {
          a = {std::min(a.x, b.x), a.y, a.width + b.width, a.height};
          merged = true;
        }
        if (merged) tiles.erase(tiles.begin() + std::ptrdiff_t(j));
      }
  }
  return tiles;
}

}  // namespace

struct WsSession;
struct HttpSession;

struct WebView::Impl {
  Wall wall;
  WebViewSettings settings;
  Control control;
  SinkLog log;
  bnet::io_context io;
  tcp::acceptor acceptor{io};
  std::thread thread;
  std::string wallJson;
  std::map<WsSession*, std::weak_ptr<WsSession>> sessions;      // the io thread's
  std::map<HttpSession*, std::weak_ptr<HttpSession>> requests;  // likewise
  std::atomic<int> viewerCount{0};
  std::mutex pendingMutex;
  std::optional<ViewerFrame> pending;
  bool encodePosted = false;
  bool stopped = false;
  bool loopback = true;  // served on a loopback address (hostAllowed)
  std::shared_ptr<bnet::steady_timer> stopTimer;

  void say(const std::string& line) {
    if (log) log(line);
  }
  bool originAllowed(const std::string& origin, const std::string& host) const {
    if (origin.empty()) return true;  // not a browser: nobody's page can be riding on it
    if (!host.empty() && origin == "http://" + host) return true;
    return std::find(settings.origins.begin(), settings.origins.end(), origin) !=
           settings.origins.end();
  }
  // DNS rebinding: a page of evil.example whose name was pointed at 127.0.0.1 reaches a loopback
  // server as a same-origin request. Served on loopback, only the loopback names (any port: an
  // SSH tunnel may use another) and the hosts of --http-origin are answered.
  bool hostAllowed(const std::string& host) const {
    if (!loopback) return true;
    std::string name = host;
    if (name.starts_with("[")) {
      name = name.substr(0, name.find(']') + 1);
    } else if (const auto colon = name.rfind(':'); colon != std::string::npos) {
      name = name.substr(0, colon);
    }
    if (name == "127.0.0.1" || name == "localhost" || name == "[::1]") return true;
    for (const auto& origin : settings.origins) {
      const auto start = origin.find("://");
      if (start != std::string::npos && origin.substr(start + 3) == host) return true;
    }
    return false;
  }
  void accept();
  void encode();
  void closeAll();
};

// One WebSocket viewer. Writes go out one at a time: queued notes first, then the newest frame.
struct WsSession : std::enable_shared_from_this<WsSession> {
  websocket::stream<beast::tcp_stream> ws;
  WebView::Impl* view;
  std::string name;
  beast::flat_buffer in;
  bool authed = false, open = false, writing = false, closing = false, counted = true;
  std::deque<std::string> notes;
  std::shared_ptr<const std::string> frame, writingFrame;
  std::string writingNote;
  double tokens = 0;
  Clock::time_point refilled = Clock::now();

  // Counted among the viewers from here (a handshake in progress takes a place too, so
  // --max-viewers bounds what handshakes can hold), until gone().
  WsSession(tcp::socket socket, WebView::Impl* v) : ws(std::move(socket)), view(v) {
    name = peerName(beast::get_lowest_layer(ws).socket());
    authed = view->settings.token.empty();
    tokens = 2 * view->settings.commandsPerSecond;
    ++view->viewerCount;
  }

  void start(http::request<http::empty_body> request) {
    websocket::stream_base::timeout t;
    t.handshake_timeout = std::chrono::seconds(10);
    t.idle_timeout = std::chrono::seconds(30);
    t.keep_alive_pings = true;
    beast::get_lowest_layer(ws).expires_never();
    ws.set_option(t);
    ws.read_message_max(kMaxViewerMessage);
    ws.async_accept(request, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return self->gone("handshake: " + ec.message());
      self->open = true;
      self->view->sessions[self.get()] = self;
      self->view->say("sink: " + self->name + " connected (" +
                      std::to_string(self->view->viewerCount.load()) + " watching)");
      self->note(self->view->wallJson);
      self->read();
    });
  }

  void gone(const std::string& why) {
    if (counted) {
      counted = false;
      const int n = --view->viewerCount;
      if (open)
        view->say("sink: " + name + " left" + (why.empty() ? "" : " (" + why + ")") + ", " +
                  std::to_string(n) + " watching");
    }
    if (open) {
      open = false;
      view->sessions.erase(this);
    }
    beast::get_lowest_layer(ws).close();
  }

  // Closes with a reason the page can show; a viewer that does not take the close is cut off.
  void refuse(websocket::close_code code, const std::string& reason) {
    if (closing) return;
    closing = true;
    view->say("sink: " + name + " closed: " + reason);
    beast::get_lowest_layer(ws).expires_after(std::chrono::seconds(5));
    ws.async_close(websocket::close_reason(code, reason.substr(0, 120)),
                   [self = shared_from_this()](beast::error_code) { self->gone(""); });
  }

  void read() {
    ws.async_read(in, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        if (ec == websocket::error::closed) return self->gone("");
        if (ec == websocket::error::message_too_big)
          return self->refuse(websocket::close_code::too_big,
                              "message over " + std::to_string(kMaxViewerMessage) + " bytes");
        return self->gone(ec.message());
      }
      if (!self->ws.got_text())
        return self->refuse(websocket::close_code::unknown_data, "binary messages are not taken");
      const std::string text = beast::buffers_to_string(self->in.data());
      self->in.consume(self->in.size());
      if (!self->take(text)) return;
      self->read();
    });
  }

  // One message from the page; false when the connection is being closed.
  bool take(const std::string& text) {
    const auto& token = view->settings.token;
    if (text.rfind("auth ", 0) == 0) {
      if (!token.empty() && !sameSecret(text.substr(5), token)) {
        refuse(websocket::close_code::policy_error, "wrong token");
        return false;
      }
      authed = true;
      note(R"({"type":"auth","ok":true})");
      return true;
    }
    if (!authed) {
      refuse(websocket::close_code::policy_error, "a command before the token");
      return false;
    }
    net::Control c;
    try {
      c = parseControlLine(text);
    } catch (const std::invalid_argument& e) {
      refuse(websocket::close_code::policy_error, e.what());
      return false;
    }
    const double rate = view->settings.commandsPerSecond;
    const auto now = Clock::now();
    tokens =
        std::min(2 * rate, tokens + rate * std::chrono::duration<double>(now - refilled).count());
    refilled = now;
    if (tokens < 1) {
      note(nlohmann::json{{"type", "error"}, {"message", "too many commands: this one dropped"}}
               .dump());
      return true;
    }
    tokens -= 1;
    if (view->control) view->control(c);
    return true;
  }

  void note(std::string text) {
    if (!open || closing) return;
    if (notes.size() >= kMaxQueuedText) {
      refuse(websocket::close_code::policy_error, "not reading");
      return;
    }
    notes.push_back(std::move(text));
    write();
  }
  // The newest frame replaces one that has not started going out.
  void offer(std::shared_ptr<const std::string> bytes) {
    if (!open || closing || !authed) return;
    frame = std::move(bytes);
    write();
  }

  void write() {
    if (writing || closing) return;
    auto done = [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->writing = false;
      self->writingFrame.reset();
      if (ec) return self->gone(ec.message());
      self->write();
    };
    if (!notes.empty()) {
      writing = true;
      writingNote = std::move(notes.front());
      notes.pop_front();
      ws.text(true);
      ws.async_write(bnet::buffer(writingNote), done);
    } else if (frame) {
      writing = true;
      writingFrame = std::move(frame);
      frame.reset();
      ws.binary(true);
      ws.async_write(bnet::buffer(*writingFrame), done);
    }
  }
};

// A plain HTTP request: the page, 404 or 405; or the WebSocket upgrade.
struct HttpSession : std::enable_shared_from_this<HttpSession> {
  beast::tcp_stream stream;
  WebView::Impl* view;
  beast::flat_buffer buffer;
  std::optional<http::request_parser<http::empty_body>> parser;

  HttpSession(tcp::socket socket, WebView::Impl* v) : stream(std::move(socket)), view(v) {}

  void start() {
    parser.emplace();
    parser->header_limit(kMaxRequestHeader);
    parser->body_limit(0);
    stream.expires_after(kRequestTimeout);
    http::async_read(stream, buffer, *parser,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) {
                       if (ec) return self->close();
                       self->serve(self->parser->release());
                     });
  }

  void close() {
    boost::system::error_code ec;
    stream.socket().shutdown(tcp::socket::shutdown_both, ec);
    stream.close();
  }

  void reply(http::status status, std::string body, const char* type, bool head = false) {
    auto res = std::make_shared<http::response<http::string_body>>(status, 11);
    res->set(http::field::server, "voxwall");
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, "no-store");
    res->set("X-Content-Type-Options", "nosniff");
    res->set("X-Frame-Options", "DENY");
    res->set("Content-Security-Policy",
             "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
             "img-src blob: data:; connect-src 'self'; base-uri 'none'; form-action 'none'");
    res->keep_alive(false);
    const auto size = body.size();
    if (!head) res->body() = std::move(body);
    res->content_length(size);
    stream.expires_after(kRequestTimeout);
    http::async_write(
        stream, *res,
        [self = shared_from_this(), res](beast::error_code, std::size_t) { self->close(); });
  }

  void serve(http::request<http::empty_body> req) {
    const std::string target(req.target());
    const std::string host(req[http::field::host]);
    if (!view->hostAllowed(host)) {
      view->say("sink: refused a request for Host '" + host.substr(0, 100) + "'");
      return reply(http::status::forbidden, "this Host is not served here\n", "text/plain");
    }
    if (websocket::is_upgrade(req)) {
      const std::string origin(req[http::field::origin]);
      if (target != "/ws")
        return reply(http::status::not_found, "no such WebSocket\n", "text/plain");
      if (!view->originAllowed(origin, host)) {
        view->say("sink: refused a viewer from Origin '" + origin.substr(0, 100) + "'");
        return reply(http::status::forbidden, "this Origin may not watch the wall\n", "text/plain");
      }
      if (view->viewerCount >= view->settings.maxViewers) {
        view->say("sink: refused a viewer: " + std::to_string(view->settings.maxViewers) +
                  " already watching");
        return reply(http::status::service_unavailable, "too many viewers\n", "text/plain");
      }
      std::make_shared<WsSession>(stream.release_socket(), view)->start(std::move(req));
      return;
    }
    const bool head = req.method() == http::verb::head;
    if (req.method() != http::verb::get && !head)
      return reply(http::status::method_not_allowed, "only GET\n", "text/plain");
    if (target == "/" || target == "/index.html")
      return reply(http::status::ok, webPage(), "text/html; charset=utf-8", head);
    return reply(http::status::not_found, "not found\n", "text/plain", head);
  }
};

void WebView::Impl::accept() {
  acceptor.async_accept([self = this](beast::error_code ec, tcp::socket socket) {
    if (self->stopped) return;
    if (ec) {
      // Out of descriptors and the like: wait a moment instead of spinning or giving up.
      self->say("sink: web: accept failed: " + ec.message());
      auto timer = std::make_shared<bnet::steady_timer>(self->io, std::chrono::milliseconds(100));
      timer->async_wait([self, timer](beast::error_code) { self->accept(); });
      return;
    }
    std::erase_if(self->requests, [](const auto& r) { return r.second.expired(); });
    if (self->requests.size() >= kMaxRequests) {  // requests in flight; each ends within 10 s
      boost::system::error_code ignored;
      socket.close(ignored);
      self->accept();
      return;
    }
    auto session = std::make_shared<HttpSession>(std::move(socket), self);
    self->requests[session.get()] = session;
    session->start();
    self->accept();
  });
}

void WebView::Impl::encode() {
  std::optional<ViewerFrame> f;
  {
    std::lock_guard lock(pendingMutex);
    encodePosted = false;
    f.swap(pending);
  }
  if (!f || !f->frame || stopped) return;
  const AssembledFrame& frame = *f->frame;
  bool anyone = false;
  for (const auto& [p, weak] : sessions)
    if (const auto s = weak.lock(); s && s->authed) anyone = true;
  if (!anyone) return;
  const voxwall::Image small = scaleDown(frame.image, settings.maxWidth);
  net::TileCodecSettings codec;
  codec.codec = net::TileCodec::Jpeg;
  codec.jpegQuality = settings.jpegQuality;
  codec.segmentPixels = std::max(small.width, small.height);
  codec.threads = 1;
  const auto parts =
      net::encodeTiles(small, {0, 0, small.width, small.height}, wall.background, codec);
  if (parts.size() != 1) return;
  nlohmann::json meta = {{"type", "frame"},
                         {"frame", frame.frame},
                         {"step", frame.step},
                         {"width", small.width},
                         {"height", small.height},
                         {"latency_ms", f->latencyMs},
                         {"bytes", frame.bytes},
                         {"presented", f->stats.framesPresented},
                         {"dropped", f->stats.framesDropped + f->stats.framesStale},
                         {"ranks_connected", f->stats.renderersConnected}};
  auto& tiles = meta["tiles"] = nlohmann::json::array();
  for (const auto& t : mergePlacements(frame.placements))
    tiles.push_back({{"rank", t.rank},
                     {"x", t.rect.x},
                     {"y", t.rect.y},
                     {"w", t.rect.width},
                     {"h", t.rect.height}});
  auto& ranks = meta["ranks"] = nlohmann::json::object();
  for (const auto& [rank, micros] : frame.rankRenderMicros)
    ranks[std::to_string(rank)] = double(micros) / 1e3;
  const std::string json = meta.dump();
  auto message = std::make_shared<std::string>();
  const auto n = std::uint32_t(json.size());
  const char length[4] = {char(n & 0xff), char((n >> 8) & 0xff), char((n >> 16) & 0xff),
                          char((n >> 24) & 0xff)};
  message->append(length, 4);
  message->append(json);
  message->append(reinterpret_cast<const char*>(parts[0].bytes.data()), parts[0].bytes.size());
  for (const auto& [p, weak] : sessions)
    if (const auto s = weak.lock()) s->offer(message);
}

void WebView::Impl::closeAll() {
  stopped = true;
  boost::system::error_code ec;
  acceptor.close(ec);
  for (const auto& [p, weak] : sessions)
    if (const auto s = weak.lock()) beast::get_lowest_layer(s->ws).close();
  for (const auto& [p, weak] : requests)
    if (const auto s = weak.lock()) s->stream.close();
}

WebView::WebView(const Wall& wall, WebViewSettings settings, Control control, SinkLog log)
    : impl_(std::make_unique<Impl>()) {
  auto& s = *impl_;
  s.wall = wall;
  s.settings = std::move(settings);
  s.control = std::move(control);
  s.log = std::move(log);
  if (s.settings.maxViewers < 1) throw std::invalid_argument("at least one viewer");
  if (s.settings.maxWidth < 16) throw std::invalid_argument("viewer frames of at least 16 pixels");
  nlohmann::json w = {{"type", "wall"},
                      {"id", wall.id},
                      {"width", wall.width},
                      {"height", wall.height},
                      {"token", !s.settings.token.empty()}};
  auto& displays = w["displays"] = nlohmann::json::array();
  for (const auto& d : wall.displays)
    displays.push_back({{"name", d.name},
                        {"x", d.rect.x},
                        {"y", d.rect.y},
                        {"w", d.rect.width},
                        {"h", d.rect.height}});
  s.wallJson = w.dump();
  try {
    const auto address = bnet::ip::make_address(s.settings.host);
    const tcp::endpoint endpoint(address, s.settings.port);
    s.loopback = address.is_loopback();
    s.acceptor.open(endpoint.protocol());
    s.acceptor.set_option(bnet::socket_base::reuse_address(true));
    s.acceptor.bind(endpoint);
    s.acceptor.listen(bnet::socket_base::max_listen_connections);
  } catch (const boost::system::system_error& e) {
    throw net::NetError("--http " + s.settings.host + ":" + std::to_string(s.settings.port) +
                        ": cannot listen: " + e.code().message());
  }
}

WebView::~WebView() { stop(); }

std::uint16_t WebView::port() const {
  boost::system::error_code ec;
  return impl_->acceptor.local_endpoint(ec).port();
}

void WebView::start() {
  impl_->accept();
  impl_->thread = std::thread([impl = impl_.get()] {
    for (;;) {
      try {
        impl->io.run();
        return;
      } catch (const std::exception& e) {
        // A viewer's trouble must never take the wall down: log it and go on serving.
        impl->say(std::string("sink: web: ") + e.what());
      }
    }
  });
}

void WebView::stop() {
  if (!impl_->thread.joinable()) return;
  // Closing every socket completes what waits on them; a moment later the thread ends (what is
  // left, e.g. a WebSocket's idle timer, is destroyed with the io_context).
  auto* impl = impl_.get();
  bnet::post(impl->io, [impl] {
    impl->closeAll();
    auto timer = std::make_shared<bnet::steady_timer>(impl->io, std::chrono::milliseconds(50));
    timer->async_wait([impl, timer](beast::error_code) { impl->io.stop(); });
    impl->stopTimer = timer;
  });
  impl->thread.join();
  impl->stopTimer.reset();
}

void WebView::present(ViewerFrame frame) {
  auto& s = *impl_;
  if (s.viewerCount == 0) return;
  std::lock_guard lock(s.pendingMutex);
  s.pending = std::move(frame);
  if (s.encodePosted) return;
  s.encodePosted = true;
  bnet::post(s.io, [impl = impl_.get()] { impl->encode(); });
}

}  // namespace voxwall::walls
