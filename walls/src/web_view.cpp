// The browser view of the wall (web_view.hpp): Boost.Beast over Boost.Asio, on a thread and an
// io_context of its own, with the displays' swap barrier; the overview's pictures are decoded and
// encoded on a thread of their own. This file must not include the standalone Asio the tile
// server uses.
// First: Boost 1.74's Asio uses std::exchange without including <utility>.
// clang-format off
#include <utility>
// clang-format on
#include <algorithm>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <thread>
#include <voxwall/walls/sink_core.hpp>
#include <voxwall/walls/swap_barrier.hpp>
#include <voxwall/walls/web_view.hpp>

#include "web_messages.hpp"

namespace voxwall::walls {

namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace bnet = boost::asio;
using tcp = bnet::ip::tcp;
using Clock = std::chrono::steady_clock;
using Page = SwapBarrier::Page;

constexpr std::size_t kMaxRequestHeader = 8192;
constexpr auto kRequestTimeout = std::chrono::seconds(10);
constexpr std::size_t kMaxQueuedText = 32;  // a viewer with more unsent notes is closed
constexpr std::size_t kMaxRequests = 256;   // HTTP requests being read or answered at once
constexpr std::size_t kSkewsKept = 16;      // swapped frames whose show times are collected

std::string peerAddress(const tcp::socket& socket) {
  boost::system::error_code ec;
  const auto ep = socket.remote_endpoint(ec);
  if (ec) return "?";
  return ep.address().to_string() + ":" + std::to_string(ep.port());
}

// "ready 12" -> 12; "shown 12 1733150000123.456" -> 12 and the time. Whole message, or nothing.
std::optional<std::uint64_t> parseUnsigned(std::string_view text) {
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

}  // namespace

struct WsSession;
struct HttpSession;

struct WebView::Impl {
  Wall wall;
  WebViewSettings settings;
  Control control;
  SinkLog log;
  SwapReport swapReport;
  bnet::io_context io;
  tcp::acceptor acceptor{io};
  std::thread thread;
  std::string wallJson;
  std::map<WsSession*, std::weak_ptr<WsSession>> sessions;      // the io thread's
  std::map<HttpSession*, std::weak_ptr<HttpSession>> requests;  // likewise
  std::atomic<int> viewerCount{0}, pageCount{0};
  bool stopped = false;
  bool loopback = true;  // served on a loopback address (hostAllowed)
  std::shared_ptr<bnet::steady_timer> stopTimer;

  // The displays' pages and their barrier (the io thread's).
  struct Held {
    ViewerFrame frame;
    std::vector<std::shared_ptr<const std::string>> messages;  // per display, made when needed
  };
  struct Skew {
    std::uint64_t seq = 0, frame = 0;
    std::set<Page> pages;  // shown together; each reports its time once
    std::vector<double> unixMs;
  };
  SwapBarrier barrier;
  std::map<Page, std::weak_ptr<WsSession>> pages;
  Page nextPage = 1;
  std::uint64_t lastSeq = 0;
  std::map<std::uint64_t, Held> frames;  // by seq: what the barrier may still send
  bnet::steady_timer barrierTimer{io};
  std::deque<Skew> skews;
  SwapStats swapStats;

  // The overview's pictures: the newest frame waits for the overview thread.
  std::mutex overviewMutex;
  std::condition_variable overviewReady;
  std::optional<ViewerFrame> overviewPending;
  bool overviewStop = false;
  std::thread overviewThread;

  explicit Impl(int swapTimeoutMs) : barrier(std::chrono::milliseconds(swapTimeoutMs)) {}

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
  // What the browser asked for, to build links with: "http://HOST:PORT".
  std::string base(const std::string& host) const {
    if (!host.empty()) return "http://" + host;
    boost::system::error_code ec;
    const auto ep = acceptor.local_endpoint(ec);
    return "http://" + ep.address().to_string() + ":" + std::to_string(ep.port());
  }
  void accept();
  void closeAll();

  // The barrier (io thread).
  void route(ViewerFrame frame);
  void pageJoined(const std::shared_ptr<WsSession>& session);
  void pageLeft(Page page);
  void pageReady(Page page, std::uint64_t seq);
  void pageShown(Page page, std::uint64_t seq, double unixMs);
  void apply(SwapBarrier::Actions actions);
  std::shared_ptr<const std::string> frameFor(std::uint64_t seq, int display);
  void armBarrierTimer();
  void reportSwap();
  std::string pageName(Page page) const;

  // The overview thread.
  void overviewLoop();
};

// One WebSocket: an overview viewer (display < 0) or a display's page. Writes go out one at a
// time: queued notes first, then the frame waiting (the newest for a viewer; for a page the one
// the barrier gave it, one in flight).
struct WsSession : std::enable_shared_from_this<WsSession> {
  websocket::stream<beast::tcp_stream> ws;
  WebView::Impl* view;
  std::string name;
  int display = -1;
  Page page = 0;  // a display page's place with the barrier, once authenticated
  beast::flat_buffer in;
  bool authed = false, open = false, writing = false, closing = false, counted = true;
  std::deque<std::string> notes;
  std::shared_ptr<const std::string> frame, writingFrame;
  std::string writingNote;
  double tokens = 0;
  Clock::time_point refilled = Clock::now();

  // Counted among the viewers (or pages) from here (a handshake in progress takes a place too,
  // so the caps bound what handshakes can hold), until gone().
  WsSession(tcp::socket socket, WebView::Impl* v, int displayIndex)
      : ws(std::move(socket)), view(v), display(displayIndex) {
    const auto address = peerAddress(beast::get_lowest_layer(ws).socket());
    name = display >= 0 ? "display page " + view->wall.displays[std::size_t(display)].name + " (" +
                              address + ")"
                        : "viewer " + address;
    authed = view->settings.token.empty();
    tokens = 2 * rate();
    ++count();
  }
  std::atomic<int>& count() { return display >= 0 ? view->pageCount : view->viewerCount; }
  double rate() const {
    return display >= 0 ? view->settings.pageMessagesPerSecond : view->settings.commandsPerSecond;
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
      auto& v = *self->view;
      self->open = true;
      v.sessions[self.get()] = self;
      if (self->display >= 0) {
        v.say("sink: " + self->name + " connected (" + std::to_string(v.pageCount.load()) +
              " display page(s))");
        self->note(web::displayJson(v.wall, v.wall.displays[std::size_t(self->display)],
                                    !v.settings.token.empty(), v.settings.swapTimeoutMs));
        if (self->authed) v.pageJoined(self);
      } else {
        v.say("sink: " + self->name + " connected (" + std::to_string(v.viewerCount.load()) +
              " watching)");
        self->note(v.wallJson);
      }
      self->read();
    });
  }

  void gone(const std::string& why) {
    if (counted) {
      counted = false;
      const int n = --count();
      if (open)
        view->say("sink: " + name + " left" + (why.empty() ? "" : " (" + why + ")") + ", " +
                  std::to_string(n) + (display >= 0 ? " display page(s)" : " watching"));
    }
    if (open) {
      open = false;
      view->sessions.erase(this);
      if (page) view->pageLeft(std::exchange(page, 0));
    }
    beast::get_lowest_layer(ws).close();
  }

  // Closes with a reason the page can show; a viewer that does not take the close is cut off.
  void refuse(websocket::close_code code, const std::string& reason) {
    if (closing) return;
    closing = true;
    view->say("sink: " + name + " closed: " + reason);
    if (page) view->pageLeft(std::exchange(page, 0));
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

  // Takes one token of the rate limit; false when there is none.
  bool withinRate() {
    const double r = rate();
    const auto now = Clock::now();
    tokens = std::min(2 * r, tokens + r * std::chrono::duration<double>(now - refilled).count());
    refilled = now;
    if (tokens < 1) return false;
    tokens -= 1;
    return true;
  }

  // One message from the page; false when the connection is being closed.
  bool take(const std::string& text) {
    const auto& token = view->settings.token;
    if (text.rfind("auth ", 0) == 0) {
      if (!token.empty() && !sameSecret(text.substr(5), token)) {
        refuse(websocket::close_code::policy_error, "wrong token");
        return false;
      }
      const bool first = !authed;
      authed = true;
      note(R"({"type":"auth","ok":true})");
      if (first && display >= 0) view->pageJoined(shared_from_this());
      return true;
    }
    if (!authed) {
      refuse(websocket::close_code::policy_error, "a command before the token");
      return false;
    }
    return display >= 0 ? takePageMessage(text) : takeCommand(text);
  }

  bool takeCommand(const std::string& text) {
    net::Control c;
    try {
      c = parseControlLine(text);
    } catch (const std::invalid_argument& e) {
      refuse(websocket::close_code::policy_error, e.what());
      return false;
    }
    if (!withinRate()) {
      note(nlohmann::json{{"type", "error"}, {"message", "too many commands: this one dropped"}}
               .dump());
      return true;
    }
    if (view->control) view->control(c);
    return true;
  }

  // "ready SEQ" | "shown SEQ UNIXMS" from a display page.
  bool takePageMessage(const std::string& text) {
    if (!withinRate()) {
      refuse(websocket::close_code::policy_error, "too many messages");
      return false;
    }
    const std::string_view t(text);
    if (t.starts_with("ready ")) {
      if (const auto seq = parseUnsigned(t.substr(6))) {
        if (page) view->pageReady(page, *seq);
        return true;
      }
    } else if (t.starts_with("shown ")) {
      const auto space = t.find(' ', 6);
      const auto seq =
          space == std::string_view::npos ? std::nullopt : parseUnsigned(t.substr(6, space - 6));
      double unixMs = 0;
      const auto rest = space == std::string_view::npos ? std::string_view() : t.substr(space + 1);
      const auto [end, ec] = std::from_chars(rest.data(), rest.data() + rest.size(), unixMs);
      if (seq && ec == std::errc() && end == rest.data() + rest.size() && !rest.empty() &&
          std::isfinite(unixMs)) {
        if (page) view->pageShown(page, *seq, unixMs);
        return true;
      }
    }
    refuse(websocket::close_code::policy_error,
           "not a display page's message: '" + text.substr(0, 40) + "'");
    return false;
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
    if (!open || closing || !authed || !bytes) return;
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

// A plain HTTP request: a page, the display list, 404 or 405; or a WebSocket upgrade.
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

  void upgrade(http::request<http::empty_body> req, const std::string& target,
               const std::string& host) {
    const std::string origin(req[http::field::origin]);
    int display = -1;
    if (target != "/ws") {
      const auto d = web::displayOfPath(view->wall, target, "/ws/display/");
      if (!d) return reply(http::status::not_found, "no such WebSocket\n", "text/plain");
      display = int(*d);
    }
    if (!view->originAllowed(origin, host)) {
      view->say("sink: refused a viewer from Origin '" + origin.substr(0, 100) + "'");
      return reply(http::status::forbidden, "this Origin may not watch the wall\n", "text/plain");
    }
    if (display < 0 && view->viewerCount >= view->settings.maxViewers) {
      view->say("sink: refused a viewer: " + std::to_string(view->settings.maxViewers) +
                " already watching");
      return reply(http::status::service_unavailable, "too many viewers\n", "text/plain");
    }
    if (display >= 0 && view->pageCount >= view->settings.maxDisplayPages) {
      view->say("sink: refused a display page: " + std::to_string(view->settings.maxDisplayPages) +
                " already open");
      return reply(http::status::service_unavailable, "too many display pages\n", "text/plain");
    }
    std::make_shared<WsSession>(stream.release_socket(), view, display)->start(std::move(req));
  }

  void serve(http::request<http::empty_body> req) {
    const std::string target(req.target());
    const std::string host(req[http::field::host]);
    if (!view->hostAllowed(host)) {
      view->say("sink: refused a request for Host '" + host.substr(0, 100) + "'");
      return reply(http::status::forbidden, "this Host is not served here\n", "text/plain");
    }
    if (websocket::is_upgrade(req)) return upgrade(std::move(req), target, host);
    const bool head = req.method() == http::verb::head;
    if (req.method() != http::verb::get && !head)
      return reply(http::status::method_not_allowed, "only GET\n", "text/plain");
    const bool token = !view->settings.token.empty();
    if (target == "/" || target == "/index.html")
      return reply(http::status::ok, webPage(), "text/html; charset=utf-8", head);
    if (target == "/displays")
      return reply(http::status::ok, web::displaysHtml(view->wall, view->base(host), token),
                   "text/html; charset=utf-8", head);
    if (target == "/displays.json")
      return reply(http::status::ok, web::displaysJson(view->wall, view->base(host)),
                   "application/json", head);
    if (web::displayOfPath(view->wall, target, "/display/"))
      return reply(http::status::ok, displayPage(), "text/html; charset=utf-8", head);
    if (target.starts_with("/display/"))
      return reply(http::status::not_found,
                   "this wall has no such display: its displays are listed at /displays\n",
                   "text/plain", head);
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
    // Small messages go out at once: the swap barrier's "show" must not wait for Nagle's
    // algorithm to gather more (40 ms per round on Linux, with delayed acknowledgements).
    boost::system::error_code ignored;
    socket.set_option(tcp::no_delay(true), ignored);
    auto session = std::make_shared<HttpSession>(std::move(socket), self);
    self->requests[session.get()] = session;
    session->start();
    self->accept();
  });
}

// A presented frame: the barrier offers it to the displays' pages.
void WebView::Impl::route(ViewerFrame frame) {
  if (stopped) return;
  const auto seq = ++lastSeq;
  frames[seq] =
      Held{std::move(frame), std::vector<std::shared_ptr<const std::string>>(wall.displays.size())};
  apply(barrier.offer(seq, Clock::now()));
}

void WebView::Impl::pageJoined(const std::shared_ptr<WsSession>& session) {
  if (stopped || session->page) return;
  session->page = nextPage++;
  pages[session->page] = session;
  apply(barrier.add(session->page, Clock::now()));
}

void WebView::Impl::pageLeft(Page page) {
  pages.erase(page);
  apply(barrier.remove(page, Clock::now()));
}

void WebView::Impl::pageReady(Page page, std::uint64_t seq) {
  apply(barrier.ready(page, seq, Clock::now()));
}

void WebView::Impl::pageShown(Page page, std::uint64_t seq, double unixMs) {
  for (auto& s : skews) {
    if (s.seq != seq || !s.pages.erase(page)) continue;
    s.unixMs.push_back(unixMs);
    if (!s.pages.empty()) return;
    const auto [lo, hi] = std::minmax_element(s.unixMs.begin(), s.unixMs.end());
    swapStats.lastSpreadMs = *hi - *lo;
    char line[160];
    std::snprintf(line, sizeof line,
                  "frame %llu shown together on %zu display page(s), spread %.1f ms",
                  (unsigned long long)s.frame, s.unixMs.size(), swapStats.lastSpreadMs);
    say(line);
    reportSwap();
    return;
  }
}

std::string WebView::Impl::pageName(Page page) const {
  const auto it = pages.find(page);
  if (it != pages.end())
    if (const auto s = it->second.lock()) return s->name;
  return "a display page";
}

std::shared_ptr<const std::string> WebView::Impl::frameFor(std::uint64_t seq, int display) {
  const auto it = frames.find(seq);
  if (it == frames.end() || display < 0) return nullptr;
  auto& message = it->second.messages[std::size_t(display)];
  if (!message)
    message = web::displayFrameMessage(*it->second.frame.frame, wall.displays[std::size_t(display)],
                                       seq, it->second.frame.latencyMs);
  return message;
}

// Shows go out before the next frame's segments: a page must never see frame N + 1 before it was
// told to show N.
void WebView::Impl::apply(SwapBarrier::Actions a) {
  for (const Page page : a.left)
    say("sink: " + pageName(page) + " left the swap barrier: not ready within " +
        std::to_string(settings.swapTimeoutMs) + " ms (it rejoins when it keeps up)");
  for (const Page page : a.joined) say("sink: " + pageName(page) + " is in the swap barrier");
  const std::string showNote = R"({"type":"show","seq":)";
  for (const auto& [page, seq] : a.show)
    if (const auto s = pages.count(page) ? pages[page].lock() : nullptr)
      s->note(showNote + std::to_string(seq) + "}");
  for (auto& [seq, shown] : a.swapped) {
    ++swapStats.framesSwapped;
    if (shown.empty()) continue;
    const auto held = frames.find(seq);
    skews.push_back({seq,
                     held != frames.end() ? held->second.frame.frame->frame : 0,
                     std::set<Page>(shown.begin(), shown.end()),
                     {}});
    if (skews.size() > kSkewsKept) skews.pop_front();
  }
  for (const auto& [page, seq] : a.send)
    if (const auto s = pages.count(page) ? pages[page].lock() : nullptr)
      s->offer(frameFor(seq, s->display));
  const auto inUse = barrier.framesInUse();
  std::erase_if(frames, [&](const auto& f) {
    return std::find(inUse.begin(), inUse.end(), f.first) == inUse.end();
  });
  armBarrierTimer();
  reportSwap();
}

void WebView::Impl::armBarrierTimer() {
  const auto deadline = barrier.deadline();
  if (!deadline) return;
  if (barrierTimer.expiry() == *deadline) return;  // already waiting for it
  barrierTimer.expires_at(*deadline);
  barrierTimer.async_wait([this](beast::error_code ec) {
    if (ec || stopped) return;  // rearmed or cancelled
    apply(barrier.expire(Clock::now()));
  });
}

void WebView::Impl::reportSwap() {
  swapStats.pages = int(barrier.pages());
  swapStats.inBarrier = int(barrier.members());
  if (swapReport) swapReport(swapStats);
}

void WebView::Impl::overviewLoop() {
  for (;;) {
    ViewerFrame next;
    {
      std::unique_lock lock(overviewMutex);
      overviewReady.wait(lock, [&] { return overviewStop || overviewPending; });
      if (overviewStop) return;
      next = std::move(*overviewPending);
      overviewPending.reset();
    }
    if (viewerCount == 0) continue;
    std::shared_ptr<const std::string> message;
    try {
      message = web::overviewFrameMessage(next, wall, settings.maxWidth, settings.jpegQuality);
    } catch (const std::exception& e) {
      say(std::string("sink: the overview page misses frame ") + std::to_string(next.frame->frame) +
          ": " + e.what());
      continue;
    }
    bnet::post(io, [this, message] {
      for (const auto& [p, weak] : sessions)
        if (const auto s = weak.lock(); s && s->display < 0) s->offer(message);
    });
  }
}

void WebView::Impl::closeAll() {
  stopped = true;
  boost::system::error_code ec;
  acceptor.close(ec);
  barrierTimer.cancel();
  for (const auto& [p, weak] : sessions)
    if (const auto s = weak.lock()) beast::get_lowest_layer(s->ws).close();
  for (const auto& [p, weak] : requests)
    if (const auto s = weak.lock()) s->stream.close();
}

WebView::WebView(const Wall& wall, WebViewSettings settings, Control control, SinkLog log,
                 SwapReport swapReport)
    : impl_(std::make_unique<Impl>(std::max(1, settings.swapTimeoutMs))) {
  auto& s = *impl_;
  s.wall = wall;
  s.settings = std::move(settings);
  s.control = std::move(control);
  s.log = std::move(log);
  s.swapReport = std::move(swapReport);
  if (s.settings.maxViewers < 1) throw std::invalid_argument("at least one viewer");
  if (s.settings.maxDisplayPages == 0)
    s.settings.maxDisplayPages = 2 * int(wall.displays.size()) + 8;
  if (s.settings.maxDisplayPages < 1) throw std::invalid_argument("at least one display page");
  if (s.settings.swapTimeoutMs < 1) throw std::invalid_argument("a positive swap timeout");
  if (s.settings.maxWidth < 16) throw std::invalid_argument("viewer frames of at least 16 pixels");
  s.wallJson = web::wallJson(wall, !s.settings.token.empty());
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
  impl_->overviewThread = std::thread([impl = impl_.get()] { impl->overviewLoop(); });
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
  auto* impl = impl_.get();
  if (impl->overviewThread.joinable()) {
    {
      std::lock_guard lock(impl->overviewMutex);
      impl->overviewStop = true;
    }
    impl->overviewReady.notify_all();
    impl->overviewThread.join();
  }
  if (!impl->thread.joinable()) return;
  // Closing every socket completes what waits on them; a moment later the thread ends (what is
  // left, e.g. a WebSocket's idle timer, is destroyed with the io_context).
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
  if (s.viewerCount > 0) {
    std::lock_guard lock(s.overviewMutex);
    s.overviewPending = frame;
  }
  s.overviewReady.notify_one();
  bnet::post(s.io, [impl = impl_.get(), frame = std::move(frame)]() mutable {
    impl->route(std::move(frame));
  });
}

}  // namespace voxwall::walls
