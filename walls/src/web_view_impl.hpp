// The web view's insides (web_view.hpp), shared by web_view.cpp (the barrier, the overview,
// the API) and web_sessions.cpp (HTTP requests and WebSockets): Boost.Beast on Boost.Asio.
// This header must not be included where the standalone Asio of the tile server is.
#pragma once

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
#include <voxwall/net/fair_share.hpp>
#include <voxwall/walls/log_throttle.hpp>
#include <voxwall/walls/sink_core.hpp>
#include <voxwall/walls/swap_barrier.hpp>
#include <voxwall/walls/token_guard.hpp>
#include <voxwall/walls/web_view.hpp>

#include "web_messages.hpp"

namespace voxwall::walls {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace bnet = boost::asio;
using tcp = bnet::ip::tcp;

using Clock = std::chrono::steady_clock;
using Page = SwapBarrier::Page;

namespace web {

inline constexpr std::size_t kMaxRequestHeader = 8192;
inline constexpr std::size_t kMaxTarget = 2048;  // a longer request target gets 414
inline constexpr auto kRequestTimeout = std::chrono::seconds(10);
inline constexpr std::size_t kMaxQueuedText = 32;  // a viewer with more unsent notes is closed
inline constexpr std::size_t kMaxRequests = 256;   // HTTP requests being read or answered at once
inline constexpr std::size_t kMaxRequestsPerAddress = 16;  // of those, from one remote address
inline constexpr std::size_t kSkewsKept = 16;  // swapped frames whose show times are collected
// A page's `shown` time further than this from the sink's clock is not used: display hosts keep
// their clocks within NTP's milliseconds, and a time from 1e308 once made a 300-digit spread.
inline constexpr double kPlausibleShownMs = 60000;
// With a token: WebSockets waiting for theirs, per remote address (all of them: viewers and pages).
inline constexpr int kMaxPendingPerAddress = 4;

}  // namespace web

struct WsSession;
struct HttpSession;

// The live connections of `pool` that `take` takes, oldest first (by their serial).
template <class Session, class Take>
std::vector<std::shared_ptr<Session>> oldestFirst(
    const std::map<Session*, std::weak_ptr<Session>>& pool, Take take) {
  std::vector<std::shared_ptr<Session>> out;
  for (const auto& [_, weak] : pool)
    if (auto s = weak.lock(); s && take(*s)) out.push_back(std::move(s));
  std::sort(out.begin(), out.end(), [](auto& a, auto& b) { return a->serial < b->serial; });
  return out;
}

// Where they come from, for net::fairShareVictim and net::oldestOfCrowd.
template <class Session>
std::vector<net::HeldPlace> placesOf(const std::vector<std::shared_ptr<Session>>& sessions) {
  std::vector<net::HeldPlace> out;
  for (const auto& s : sessions) out.push_back({s->group(), s->address});
  return out;
}

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
  LogThrottle refusals;  // the io thread's: refusals told at most once every 10 s per kind
  // The io thread's: pages and viewers connecting, leaving, joining the swap barrier; at most 8
  // lines every 10 s per display (and for viewers), so churn cannot flood the log while a wall's
  // pages coming up are all told.
  LogThrottle comings{8};
  std::atomic<int> viewerCount{0}, pageCount{0};
  // With a token, WebSockets that have not authenticated yet: they hold no viewer's or page's
  // place, at most kMaxPendingPerAddress per address and maxViewers + maxDisplayPages in all.
  TokenGuard tokenGuard{""};  // the io thread's: the token and its back-off per address
  // Viewers' camera commands per remote address (a burst of twice the rate, refilled at the
  // rate), so reconnecting does not refill them. The io thread's; at most 4096 addresses.
  struct Budget {
    double tokens = 0;
    Clock::time_point refilled{};
  };
  std::map<std::string, Budget> commandBudget;
  int pendingAuth = 0;                          // the io thread's
  std::map<std::string, int> pendingByAddress;  // likewise
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
    std::set<Page> pages;      // shown together and not reported yet; each reports its time once
    std::size_t together = 0;  // pages that showed it together
    std::vector<double> unixMs;
  };
  SwapBarrier barrier;
  std::map<Page, std::weak_ptr<WsSession>> pages;
  Page nextPage = 1;
  std::uint64_t nextSerial = 1;  // WebSockets in the order they came (the io thread's)
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
  // `host` is a well-formed authority (web::hostOfAuthority).
  bool hostAllowed(const std::string& host) const {
    if (!loopback) return true;
    const std::string name = web::hostOfAuthority(host).value_or("");
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
  // A request or WebSocket refused: "sink: web: refused <what>", at most once every 10 s per
  // `kind`, with the count of those not told.
  void refused(const std::string& kind, const std::string& what);
  // Room for one more page of `display` (viewer: -1) from `address` when their places are all
  // held: the place fairShareVictim picks is let go (told why). Whether there is room now.
  bool makeRoom(int display, const std::string& address);
  // A page or viewer came, went or joined the barrier: `line` through `comings`, by display.
  void sayComing(int display, const std::string& line);
  void sayOfPage(Page page, const std::string& line);
  void closeAll();

  // The barrier (io thread).
  void route(ViewerFrame frame);
  void pageJoined(const std::shared_ptr<WsSession>& session);
  void pageLeft(Page page);
  void pageReady(Page page, std::uint64_t seq);
  void pageShown(Page page, std::uint64_t seq, double unixMs);
  // The "shown together" line of a swapped frame, from the times its pages reported (those that
  // did not, or said an implausible time, are counted); nothing when none reported.
  void reportSkew(const Skew& s);
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
  std::string address;  // remote, without the port
  bool authed = false, open = false, writing = false, closing = false, counted = true;
  bool pending = false;  // counted among those waiting for their token, not the viewers (pages)
  bnet::steady_timer authDeadline;   // a token must come by then
  bnet::steady_timer writeDeadline;  // a write in flight longer than this: it reads nothing
  std::uint64_t writes = 0;          // writes started (tells the write deadline which it is for)
  // A viewer is sent a frame only once it said "next" after the last one (one frame in flight,
  // not a socket buffer of them): a slow viewer gets the newest frame, not a backlog.
  bool awaitingNext = false;
  Clock::time_point frameSentAt{};
  std::deque<std::string> notes;
  std::shared_ptr<const std::string> frame, writingFrame;
  std::string writingNote;
  double tokens = 0;  // a display page's message budget (viewers': commandBudget)
  Clock::time_point refilled = Clock::now();
  std::uint64_t serial = 0;  // the order it came in: the oldest of a crowd is replaced first
  int group() const { return display; }

  // Counted among the viewers (or pages) from here (a handshake in progress takes a place too,
  // so the caps bound what handshakes can hold), until gone(); with a token, among those waiting
  // for theirs until it comes.
  WsSession(tcp::socket socket, WebView::Impl* v, int displayIndex);
  std::atomic<int>& count() { return display >= 0 ? view->pageCount : view->viewerCount; }
  double rate() const;  // messages a second it may send
  void start(http::request<http::empty_body> request);
  void gone(const std::string& why);
  void welcome();   // authenticated: logged, told the wall (or display), a page joins
  int cap() const;  // the most viewers (or pages) at once
  void unpend();    // no longer counted among those waiting for their token
  // Gives its place (or its place in the waiting pool) up to a newcomer (net/fair_share.hpp): no
  // longer counted, closed with `why`.
  void replace(const std::string& why);
  // Closes with a reason the page can show; a viewer that does not take the close is cut off.
  void refuse(websocket::close_code code, const std::string& reason);
  void read();
  // Takes one token of the rate limit; false when there is none.
  bool withinRate();
  // One message from the page; false when the connection is being closed.
  bool take(const std::string& text);
  bool takeCommand(const std::string& text);      // an overview's camera command
  bool takePageMessage(const std::string& text);  // "ready SEQ" | "shown SEQ UNIXMS"
  void note(std::string text);
  // The newest frame replaces one that has not started going out.
  void offer(std::shared_ptr<const std::string> bytes);
  void write();
};

// A plain HTTP request: a page, the display list, 404 or 405; or a WebSocket upgrade.
struct HttpSession : std::enable_shared_from_this<HttpSession> {
  beast::tcp_stream stream;
  WebView::Impl* view;
  std::string address;  // remote, without the port
  beast::flat_buffer buffer;
  std::optional<http::request_parser<http::empty_body>> parser;
  std::uint64_t serial = 0;  // the order it came in: the oldest of a crowd is replaced first
  int group() const { return -1; }

  HttpSession(tcp::socket socket, WebView::Impl* v);
  void start();
  void close();
  void reply(http::status status, std::string body, const char* type, bool head = false);
  void upgrade(http::request<http::empty_body> req, const std::string& target,
               const std::string& host);
  void serve(http::request<http::empty_body> req);
};

}  // namespace voxwall::walls
