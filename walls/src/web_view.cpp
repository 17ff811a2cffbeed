// The browser view of the wall (web_view.hpp): the displays' swap barrier and what goes to
// the pages, the overview's thread, and the API. The connections are web_sessions.cpp's.
// First: Boost 1.74's Asio uses std::exchange without including <utility>.
// clang-format off
#include <utility>
// clang-format on
#include <cmath>
#include <voxwall/core/text.hpp>

#include "web_messages.hpp"
#include "web_view_impl.hpp"

namespace voxwall::walls {

using namespace web;

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
  const double nowMs =
      std::chrono::duration<double, std::milli>(std::chrono::system_clock::now().time_since_epoch())
          .count();
  for (auto it = skews.begin(); it != skews.end(); ++it) {
    if (it->seq != seq || !it->pages.erase(page)) continue;
    if (std::abs(unixMs - nowMs) <= kPlausibleShownMs) it->unixMs.push_back(unixMs);
    if (!it->pages.empty()) return;
    reportSkew(*it);
    skews.erase(it);
    return;
  }
}

void WebView::Impl::reportSkew(const Skew& s) {
  if (s.unixMs.empty()) return;
  const auto [lo, hi] = std::minmax_element(s.unixMs.begin(), s.unixMs.end());
  swapStats.lastSpreadMs = *hi - *lo;
  char line[160];
  std::snprintf(line, sizeof line,
                "frame %llu shown together on %zu display page(s), spread %.1f ms",
                (unsigned long long)s.frame, s.together, swapStats.lastSpreadMs);
  const std::size_t silent = s.together - s.unixMs.size();
  say(line + (silent ? ", from the times of " + std::to_string(s.unixMs.size()) + " (" +
                           std::to_string(silent) + " said none or an implausible one)"
                     : std::string()));
  reportSwap();
}

std::string WebView::Impl::pageName(Page page) const {
  const auto it = pages.find(page);
  if (it != pages.end())
    if (const auto s = it->second.lock()) return s->name;
  return "a display page";
}

void WebView::Impl::sayOfPage(Page page, const std::string& line) {
  const auto it = pages.find(page);
  const auto session = it != pages.end() ? it->second.lock() : nullptr;
  sayComing(session ? session->display : -1, line);
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
  // A page's comings and goings in the barrier are a page's to cause (one without a token, too):
  // told through the throttle of its display's lines.
  for (const Page page : a.left)
    sayOfPage(page, "sink: " + pageName(page) + " left the swap barrier: not ready within " +
                        std::to_string(settings.swapTimeoutMs) +
                        " ms (it rejoins when it keeps up)");
  for (const auto& slow : a.slowed)
    sayOfPage(slow.page,
              formatLine("sink: %s left the swap barrier: ready %.0f ms after the round began, the "
                         "other pages in %.0f ms, a frame every %.0f ms, %d rounds in a row (it is "
                         "shown frames alone and rejoins when it keeps up)",
                         pageName(slow.page).c_str(), slow.readyMs, slow.othersMs, slow.intervalMs,
                         SwapBarrier::kSlowRounds));
  for (const Page page : a.joined)
    sayOfPage(page, "sink: " + pageName(page) + " is in the swap barrier");
  char at[48];
  std::snprintf(
      at, sizeof at, R"(,"at":%.3f})",
      std::chrono::duration<double, std::milli>(std::chrono::system_clock::now().time_since_epoch())
              .count() +
          settings.swapLeadMs);
  for (const auto& [page, seq] : a.show)
    if (const auto s = pages.count(page) ? pages[page].lock() : nullptr)
      s->note(R"({"type":"show","seq":)" + std::to_string(seq) + at);
  for (auto& [seq, shown] : a.swapped) {
    ++swapStats.framesSwapped;
    if (shown.empty()) continue;
    const auto held = frames.find(seq);
    skews.push_back({seq,
                     held != frames.end() ? held->second.frame.frame->frame : 0,
                     std::set<Page>(shown.begin(), shown.end()),
                     shown.size(),
                     {}});
    if (skews.size() > kSkewsKept) {
      // A page that never says `shown` does not silence the log: the frame is reported with the
      // times that came once it is this old.
      reportSkew(skews.front());
      skews.pop_front();
    }
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
  s.tokenGuard = TokenGuard(s.settings.token);
  s.control = std::move(control);
  s.log = std::move(log);
  s.swapReport = std::move(swapReport);
  if (s.settings.maxViewers < 1) throw std::invalid_argument("at least one viewer");
  if (s.settings.maxDisplayPages == 0)
    s.settings.maxDisplayPages = 2 * int(wall.displays.size()) + 8;
  if (s.settings.maxDisplayPages < 1) throw std::invalid_argument("at least one display page");
  if (s.settings.swapTimeoutMs < 1) throw std::invalid_argument("a positive swap timeout");
  if (s.settings.authTimeoutMs < 1 || s.settings.writeTimeoutMs < 1)
    throw std::invalid_argument("positive viewer deadlines");
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
