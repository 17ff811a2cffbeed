// The web view's connections (web_view_impl.hpp): HTTP requests (the pages, the display list,
// 404 and 405, WebSocket upgrades) and WebSockets (overview viewers and display pages).
// First: Boost 1.74's Asio uses std::exchange without including <utility>.
// clang-format off
#include <utility>
// clang-format on
#include <voxwall/core/text.hpp>

#include "web_messages.hpp"
#include "web_view_impl.hpp"

namespace voxwall::walls {

using namespace web;

namespace {

std::string peerAddress(const tcp::socket& socket) {
  boost::system::error_code ec;
  const auto ep = socket.remote_endpoint(ec);
  if (ec) return "?";
  return ep.address().to_string() + ":" + std::to_string(ep.port());
}

// The remote address without its port.
std::string hostOf(const tcp::socket& socket) {
  boost::system::error_code ec;
  const auto ep = socket.remote_endpoint(ec);
  return ec ? "?" : ep.address().to_string();
}

// "ready 12" -> 12: the whole text a number, or nothing.
std::optional<std::uint64_t> parseUnsigned(std::string_view text) {
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

}  // namespace

WsSession::WsSession(tcp::socket socket, WebView::Impl* v, int displayIndex)
    : ws(std::move(socket)),
      view(v),
      display(displayIndex),
      authDeadline(ws.get_executor()),
      writeDeadline(ws.get_executor()) {
  const auto& socketRef = beast::get_lowest_layer(ws).socket();
  const auto remote = peerAddress(socketRef);
  address = hostOf(socketRef);
  name = display >= 0 ? "display page " + view->wall.displays[std::size_t(display)].name + " (" +
                            remote + ")"
                      : "viewer " + remote;
  authed = view->settings.token.empty();
  serial = view->nextSerial++;
  tokens = 2 * rate();
  pending = !authed;
  if (pending) {
    ++view->pendingAuth;
    ++view->pendingByAddress[address];
  } else {
    ++count();
  }
}

int WsSession::cap() const {
  return display >= 0 ? view->settings.maxDisplayPages : view->settings.maxViewers;
}

void WsSession::unpend() {
  if (!pending) return;
  pending = false;
  --view->pendingAuth;
  if (--view->pendingByAddress[address] <= 0) view->pendingByAddress.erase(address);
}

void WsSession::replace(const std::string& why) {
  if (counted) {  // its place is free now, not when the close handshake ends
    counted = false;
    if (pending)
      unpend();
    else
      --count();
  }
  refuse(websocket::close_code::try_again_later, why);
}

bool WebView::Impl::makeRoom(int display, const std::string& address) {
  const auto holders = oldestFirst(sessions, [&](const WsSession& s) {
    return s.counted && !s.pending && !s.closing && (s.display < 0) == (display < 0);
  });
  const int victim = net::fairShareVictim(placesOf(holders), display, address);
  if (victim < 0) return false;
  WsSession& gone = *holders[std::size_t(victim)];
  const std::string why =
      display < 0
          ? "replaced: the viewers' places are full and " + gone.address + " held the most of them"
          : "replaced: the display pages' places are full and " +
                (gone.display == display ? gone.address + " held the most of this display's"
                                         : std::string("this display held the most"));
  refused(display < 0 ? "replaced-viewer" : "replaced-page", gone.name + " " + why);
  gone.replace(why);
  return true;
}

double WsSession::rate() const {
  return display >= 0 ? view->settings.pageMessagesPerSecond : view->settings.commandsPerSecond;
}

void WsSession::start(http::request<http::empty_body> request) {
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
    if (!self->authed) {  // a token must come within the deadline
      const int ms = v.settings.authTimeoutMs;
      self->authDeadline.expires_after(std::chrono::milliseconds(ms));
      self->authDeadline.async_wait([self, ms](beast::error_code e) {
        if (e || self->authed || !self->open || self->closing) return;
        self->refuse(websocket::close_code::policy_error, "no token within " + durationText(ms));
      });
    }
    if (self->authed) {
      self->welcome();
    } else {
      self->note(R"({"type":"login"})");  // nothing about the wall before the token
    }
    self->read();
  });
}

// Once authenticated (at once without a token): logged (with a token, those that never send the
// right one are told only by the token guard's lines, so guessing cannot flood the log), told the
// wall or its display, and a page joins the swap barrier.
void WsSession::welcome() {
  view->sayComing(display, "sink: " + name + " connected (" + std::to_string(count().load()) +
                               (display >= 0 ? " display page(s))" : " watching)"));
  if (display < 0) return note(view->wallJson);
  note(web::displayJson(view->wall, view->wall.displays[std::size_t(display)],
                        !view->settings.token.empty(), view->settings.swapTimeoutMs));
  view->pageJoined(shared_from_this());
}

void WsSession::gone(const std::string& why) {
  authDeadline.cancel();
  writeDeadline.cancel();
  if (counted) {
    counted = false;
    const bool wasPending = pending;
    const int n = pending ? count().load() : --count();
    unpend();
    if (open && !wasPending)
      view->sayComing(display, "sink: " + name + " left" + (why.empty() ? "" : " (" + why + ")") +
                                   ", " + std::to_string(n) +
                                   (display >= 0 ? " display page(s)" : " watching"));
  }
  if (open) {
    open = false;
    view->sessions.erase(this);
    if (page) view->pageLeft(std::exchange(page, 0));
  }
  beast::get_lowest_layer(ws).close();
}

void WsSession::refuse(websocket::close_code code, const std::string& reason) {
  if (closing) return;
  closing = true;
  if (!pending) view->sayComing(display, "sink: " + name + " closed: " + reason);
  if (page) view->pageLeft(std::exchange(page, 0));
  beast::get_lowest_layer(ws).expires_after(std::chrono::seconds(5));
  ws.async_close(websocket::close_reason(code, reason.substr(0, 120)),
                 [self = shared_from_this()](beast::error_code) { self->gone(""); });
}

void WsSession::read() {
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

bool WsSession::withinRate() {
  const double r = rate();
  const auto now = Clock::now();
  double* left = &tokens;
  Clock::time_point* when = &refilled;
  if (display < 0) {  // a viewer: its address's budget
    auto& budget = view->commandBudget;
    auto it = budget.find(address);
    if (it == budget.end()) {
      if (budget.size() >= 4096) {  // forget the budgets that are full again, then the oldest
        std::erase_if(budget, [&](const auto& b) {
          return now - b.second.refilled > std::chrono::seconds(2);
        });
        if (budget.size() >= 4096) budget.erase(budget.begin());
      }
      it = budget.emplace(address, WebView::Impl::Budget{2 * r, now}).first;
    }
    left = &it->second.tokens, when = &it->second.refilled;
  }
  *left = std::min(2 * r, *left + r * std::chrono::duration<double>(now - *when).count());
  *when = now;
  if (*left < 1) return false;
  *left -= 1;
  return true;
}

bool WsSession::take(const std::string& text) {
  if (closing) return false;  // refused or replaced: what it still says is not heard
  if (text.rfind("auth ", 0) == 0) {
    // The tile port's back-off per address: guessing gains nothing from speed.
    const auto checked = view->tokenGuard.check(address, text.substr(5));
    if (checked.verdict == TokenGuard::Verdict::BackingOff) {
      refuse(websocket::close_code::policy_error,
             "too many wrong tokens from " + address + "; try again in a few seconds");
      return false;
    }
    if (checked.verdict == TokenGuard::Verdict::Wrong) {
      if (!checked.logLine.empty()) view->say("sink: " + name + ": " + checked.logLine);
      refuse(websocket::close_code::policy_error, "wrong token");
      return false;
    }
    const bool first = !authed;
    if (pending) {  // it takes a viewer's (page's) place now
      if (count() >= cap() && !view->makeRoom(display, address)) {
        refuse(websocket::close_code::try_again_later,
               display >= 0 ? "too many display pages" : "too many viewers");
        return false;
      }
      unpend();
      ++count();
    }
    authed = true;
    authDeadline.cancel();
    note(R"({"type":"auth","ok":true})");
    if (first) welcome();
    return true;
  }
  if (!authed) {
    refuse(websocket::close_code::policy_error, "a command before the token");
    return false;
  }
  if (display < 0 && text == "next") {  // the viewer took its frame: the newest may go
    awaitingNext = false;
    write();
    return true;
  }
  return display >= 0 ? takePageMessage(text) : takeCommand(text);
}

bool WsSession::takeCommand(const std::string& text) {
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

bool WsSession::takePageMessage(const std::string& text) {
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
         "not a display page's message: " + quotedForLog(text, 40));
  return false;
}

void WsSession::note(std::string text) {
  if (!open || closing) return;
  if (notes.size() >= kMaxQueuedText) {
    refuse(websocket::close_code::policy_error, "not reading");
    return;
  }
  notes.push_back(std::move(text));
  write();
}

void WsSession::offer(std::shared_ptr<const std::string> bytes) {
  if (!open || closing || !authed || !bytes) return;
  frame = std::move(bytes);
  // A viewer that has not taken its last frame for the write deadline while newer ones came reads
  // nothing, whatever it sends.
  const int ms = view->settings.writeTimeoutMs;
  if (display < 0 && awaitingNext && Clock::now() - frameSentAt > std::chrono::milliseconds(ms)) {
    // Not from here: the caller walks the sessions that gone() leaves.
    closing = true;
    bnet::post(ws.get_executor(), [self = shared_from_this(), ms] {
      self->gone("read nothing for " + durationText(ms));
    });
    return;
  }
  write();
}

void WsSession::write() {
  if (writing || closing) return;
  auto done = [self = shared_from_this()](beast::error_code ec, std::size_t) {
    self->writing = false;
    self->writingFrame.reset();
    self->writeDeadline.cancel();
    if (ec) return self->gone(ec.message());
    self->write();
  };
  if (!notes.empty()) {
    writing = true;
    writingNote = std::move(notes.front());
    notes.pop_front();
    ws.text(true);
    ws.async_write(bnet::buffer(writingNote), done);
  } else if (frame && !(display < 0 && awaitingNext)) {
    if (display < 0) awaitingNext = true, frameSentAt = Clock::now();
    writing = true;
    writingFrame = std::move(frame);
    frame.reset();
    ws.binary(true);
    ws.async_write(bnet::buffer(*writingFrame), done);
  }
  if (!writing) return;
  // Judged by what it reads, not by what it sends: a viewer whose last write has not gone out by
  // then (it sends pongs, or commands, but reads nothing) is cut off.
  const auto generation = ++writes;
  const int ms = view->settings.writeTimeoutMs;
  writeDeadline.expires_after(std::chrono::milliseconds(ms));
  writeDeadline.async_wait([self = shared_from_this(), generation, ms](beast::error_code e) {
    if (e || !self->writing || self->writes != generation) return;
    self->gone("read nothing for " + durationText(ms));
  });
}

HttpSession::HttpSession(tcp::socket socket, WebView::Impl* v)
    : stream(std::move(socket)),
      view(v),
      address(hostOf(stream.socket())),
      serial(v->nextSerial++) {}

void HttpSession::start() {
  parser.emplace();
  parser->header_limit(kMaxRequestHeader);
  parser->body_limit(0);
  stream.expires_after(kRequestTimeout);
  http::async_read(stream, buffer, *parser,
                   [self = shared_from_this()](beast::error_code ec, std::size_t) {
                     if (ec == http::error::header_limit)
                       return self->reply(
                           http::status::request_header_fields_too_large,
                           "request headers over " + std::to_string(kMaxRequestHeader) + " bytes\n",
                           "text/plain");
                     if (ec) return self->close();
                     self->serve(self->parser->release());
                   });
}

void HttpSession::close() {
  boost::system::error_code ec;
  stream.socket().shutdown(tcp::socket::shutdown_both, ec);
  stream.close();
}

void HttpSession::reply(http::status status, std::string body, const char* type, bool head) {
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
  http::async_write(stream, *res, [self = shared_from_this(), res](beast::error_code, std::size_t) {
    self->close();
  });
}

void HttpSession::upgrade(http::request<http::empty_body> req, const std::string& target,
                          const std::string& host) {
  const std::string origin(req[http::field::origin]);
  int display = -1;
  if (target != "/ws") {
    const auto d = web::displayOfPath(view->wall, target, "/ws/display/");
    if (!d) return reply(http::status::not_found, "no such WebSocket\n", "text/plain");
    display = int(*d);
  }
  if (!view->originAllowed(origin, host)) {
    view->refused("origin", "a viewer from Origin " + quotedForLog(origin, 100));
    return reply(http::status::forbidden, "this Origin may not watch the wall\n", "text/plain");
  }
  if (!view->settings.token.empty()) {
    // Connections waiting for their token hold no viewer's place, but are few per address.
    const auto mine = view->pendingByAddress.find(address);
    if (mine != view->pendingByAddress.end() && mine->second >= kMaxPendingPerAddress) {
      view->refused("pending-address", "a WebSocket: " + std::to_string(kMaxPendingPerAddress) +
                                           " from " + address + " are waiting for their token");
      return reply(http::status::service_unavailable, "too many waiting for their token\n",
                   "text/plain");
    }
    if (view->pendingAuth >= view->settings.maxViewers + view->settings.maxDisplayPages) {
      // Full of the unproven: the oldest of the address waiting most goes (net::oldestOfCrowd).
      const auto waiting =
          oldestFirst(view->sessions, [](const WsSession& s) { return s.pending && !s.closing; });
      const int victim = net::oldestOfCrowd(placesOf(waiting));
      if (victim < 0) {  // all still in their handshake
        view->refused("pending", "a WebSocket: " + std::to_string(view->pendingAuth) +
                                     " are waiting for their token");
        return reply(http::status::service_unavailable, "too many waiting for their token\n",
                     "text/plain");
      }
      view->refused("pending-replaced",
                    waiting[std::size_t(victim)]->name + ": replaced by a newer connection (" +
                        std::to_string(view->pendingAuth) + " were waiting for their token)");
      waiting[std::size_t(victim)]->replace("replaced: too many waiting for their token");
    }
  }
  // Without a token a WebSocket takes its place now (with one, when its token comes: take()),
  // replacing one of a crowd (fair_share.hpp) when the places are all held.
  const bool open = view->settings.token.empty();
  if (open && display < 0 && view->viewerCount >= view->settings.maxViewers &&
      !view->makeRoom(display, address)) {
    view->refused("viewers",
                  "a viewer: " + std::to_string(view->settings.maxViewers) + " already watching");
    return reply(http::status::service_unavailable, "too many viewers\n", "text/plain");
  }
  if (open && display >= 0 && view->pageCount >= view->settings.maxDisplayPages &&
      !view->makeRoom(display, address)) {
    view->refused("pages", "a display page: " + std::to_string(view->settings.maxDisplayPages) +
                               " already open");
    return reply(http::status::service_unavailable, "too many display pages\n", "text/plain");
  }
  std::make_shared<WsSession>(stream.release_socket(), view, display)->start(std::move(req));
}

void HttpSession::serve(http::request<http::empty_body> req) {
  const std::string target(req.target());
  const std::string host(req[http::field::host]);
  // One Host header, an authority as RFC 3986 writes it (RFC 9112: else 400).
  if (req.count(http::field::host) != 1 || !web::hostOfAuthority(host)) {
    view->refused("host-syntax",
                  "a request with a malformed or repeated Host " + quotedForLog(host, 100));
    return reply(http::status::bad_request, "one Host header, HOST[:PORT]\n", "text/plain");
  }
  if (target.size() > kMaxTarget)
    return reply(http::status::uri_too_long,
                 "request target over " + std::to_string(kMaxTarget) + " bytes\n", "text/plain");
  if (!view->hostAllowed(host)) {
    view->refused("host", "a request for Host " + quotedForLog(host, 100));
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

void WebView::Impl::sayComing(int display, const std::string& line) {
  const std::string told =
      comings.line(display < 0 ? "viewers" : "display " + std::to_string(display), line);
  if (!told.empty()) say(told);
}

void WebView::Impl::refused(const std::string& kind, const std::string& what) {
  const std::string line = refusals.line(kind, "sink: web: refused " + what);
  if (!line.empty()) say(line);
}

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
    // Requests in flight, each ending within 10 s: at most 256, 16 from one address, so slow
    // requests from one client (a slowloris) leave room for the others.
    const std::string from = hostOf(socket);
    std::size_t fromThere = 0;
    for (const auto& [p, weak] : self->requests)
      if (const auto r = weak.lock(); r && r->address == from) ++fromThere;
    if (fromThere >= kMaxRequestsPerAddress) {
      self->refused("address", "a connection: " + std::to_string(fromThere) +
                                   " requests in flight from " + from);
      boost::system::error_code ignored;
      socket.close(ignored);
      self->accept();
      return;
    }
    if (self->requests.size() >= kMaxRequests) {
      // Full of requests from other addresses: the oldest of the address with the most in
      // flight is closed unanswered (net::oldestOfCrowd) and this one comes in.
      const auto inFlight = oldestFirst(self->requests, [](const HttpSession&) { return true; });
      if (const int victim = net::oldestOfCrowd(placesOf(inFlight)); victim >= 0) {
        self->refused("requests", "a request from " + inFlight[std::size_t(victim)]->address +
                                      ": " + std::to_string(self->requests.size()) +
                                      " requests in flight, its address had the most");
        inFlight[std::size_t(victim)]->close();
        self->requests.erase(inFlight[std::size_t(victim)].get());
      }
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

}  // namespace voxwall::walls
