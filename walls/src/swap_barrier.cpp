#include <algorithm>
#include <stdexcept>
#include <voxwall/walls/swap_barrier.hpp>

namespace voxwall::walls {

SwapBarrier::SwapBarrier(std::chrono::milliseconds timeout) : timeout_(timeout) {
  if (timeout_.count() < 1) throw std::invalid_argument("the swap timeout must be positive");
}

std::optional<std::uint64_t> SwapBarrier::target() const {
  return round_ ? std::optional(round_->frame) : lastShown_;
}

void SwapBarrier::pump(Page page, Actions& a) {
  auto& p = pages_.at(page);
  const auto want = target();
  if (!want || p.inFlight || p.sent == want) return;
  p.inFlight = p.sent = want;
  a.send.emplace_back(page, *want);
}

void SwapBarrier::start(std::uint64_t frame, Clock::time_point now, Actions& a) {
  Round r;
  r.frame = frame;
  r.started = now;
  r.deadline = now + timeout_;
  const bool anyMember = members() > 0;
  for (const auto& [page, state] : pages_)
    if (state.member || !anyMember) r.waiting.insert(page);
  round_ = std::move(r);
  for (const auto& [page, state] : pages_) pump(page, a);
  if (round_->waiting.empty()) finish(now, a);  // nobody to wait for
}

std::optional<double> SwapBarrier::streamIntervalMs() const {
  if (intervalsMs_.size() < 3) return std::nullopt;
  std::vector<double> v = intervalsMs_;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
  return v[v.size() / 2];
}

void SwapBarrier::judgeSlowness(const Round& r, Actions& a) {
  const auto interval = streamIntervalMs();
  if (!interval || r.readyMs.size() < 2) return;
  for (const auto& [page, ms] : r.readyMs) {
    std::vector<double> others;
    for (const auto& [other, otherMs] : r.readyMs)
      if (other != page) others.push_back(otherMs);
    std::nth_element(others.begin(), others.begin() + std::ptrdiff_t(others.size() / 2),
                     others.end());
    const double median = others[others.size() / 2];
    const auto it = pages_.find(page);
    if (it == pages_.end()) continue;
    auto& p = it->second;
    if (ms <= 2 * *interval || ms <= 3 * median) {
      p.slowRounds = 0;
      continue;
    }
    if (++p.slowRounds < kSlowRounds) continue;
    p.member = false;
    p.outForSlowness = true;
    p.slowRounds = p.inTime = 0;
    a.slowed.push_back({page, ms, median, *interval});
  }
}

void SwapBarrier::finish(Clock::time_point now, Actions& a) {
  Round r = std::move(*round_);
  round_.reset();
  judgeSlowness(r, a);
  std::vector<Page> shown(r.ready.begin(), r.ready.end());
  for (const Page page : shown) a.show.emplace_back(page, r.frame);
  a.swapped.emplace_back(r.frame, std::move(shown));
  lastShown_ = r.frame;
  if (queued_) {
    const auto next = *queued_;
    queued_.reset();
    start(next, now, a);
  }
}

SwapBarrier::Actions SwapBarrier::add(Page page, Clock::time_point) {
  Actions a;
  pages_[page] = PageState{};
  pump(page, a);
  return a;
}

SwapBarrier::Actions SwapBarrier::remove(Page page, Clock::time_point now) {
  Actions a;
  pages_.erase(page);
  if (round_) {
    round_->ready.erase(page);
    round_->readyMs.erase(page);
    if (round_->waiting.erase(page) && round_->waiting.empty()) finish(now, a);
  }
  return a;
}

SwapBarrier::Actions SwapBarrier::offer(std::uint64_t frame, Clock::time_point now) {
  Actions a;
  if (lastOffer_) {
    if (intervalsMs_.size() == 9) intervalsMs_.erase(intervalsMs_.begin());
    intervalsMs_.push_back(std::chrono::duration<double, std::milli>(now - *lastOffer_).count());
  }
  lastOffer_ = now;
  if (round_) {
    if (queued_) a.skipped.push_back(*queued_);
    queued_ = frame;
  } else if (pages_.empty()) {
    lastShown_ = frame;  // nobody to show it to; a page that comes gets it
  } else {
    start(frame, now, a);
  }
  return a;
}

SwapBarrier::Actions SwapBarrier::ready(Page page, std::uint64_t frame, Clock::time_point now) {
  Actions a;
  const auto it = pages_.find(page);
  if (it == pages_.end() || it->second.inFlight != frame) return a;  // not what it was given
  auto& p = it->second;
  p.inFlight.reset();
  if (round_ && round_->frame == frame) {
    readyInTime(page, p, now, a);
  } else {
    a.show.emplace_back(page, frame);  // its round is over: show it alone, behind the others
    p.inTime = 0;
  }
  if (pages_.count(page)) pump(page, a);
  return a;
}

void SwapBarrier::readyInTime(Page page, PageState& p, Clock::time_point now, Actions& a) {
  round_->ready.insert(page);
  if (p.member)
    round_->readyMs[page] =
        std::chrono::duration<double, std::milli>(now - round_->started).count();
  else if (!p.outForSlowness || ++p.inTime >= kSlowRounds) {
    p.member = true;
    p.outForSlowness = false;
    p.slowRounds = p.inTime = 0;
    a.joined.push_back(page);
  }
  if (round_->waiting.erase(page) && round_->waiting.empty()) finish(now, a);
}

SwapBarrier::Actions SwapBarrier::expire(Clock::time_point now) {
  Actions a;
  if (!round_ || now < round_->deadline) return a;
  for (const Page page : round_->waiting) {
    auto& p = pages_.at(page);
    if (p.member) a.left.push_back(page);
    p.member = false;
  }
  finish(now, a);
  return a;
}

std::optional<SwapBarrier::Clock::time_point> SwapBarrier::deadline() const {
  if (!round_) return std::nullopt;
  return round_->deadline;
}

std::vector<std::uint64_t> SwapBarrier::framesInUse() const {
  std::vector<std::uint64_t> out;
  if (round_) out.push_back(round_->frame);
  if (queued_) out.push_back(*queued_);
  if (lastShown_) out.push_back(*lastShown_);
  return out;
}

bool SwapBarrier::member(Page page) const {
  const auto it = pages_.find(page);
  return it != pages_.end() && it->second.member;
}

std::size_t SwapBarrier::members() const {
  return std::size_t(
      std::count_if(pages_.begin(), pages_.end(), [](const auto& p) { return p.second.member; }));
}

}  // namespace voxwall::walls
