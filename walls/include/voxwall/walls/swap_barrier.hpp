// The swap barrier of the displays' pages: every display of the wall switches to frame N
// together, and the wall never waits on a dead or slow page.
//
// One round per frame:
//   1. the sink sends the frame's segments to every page, one frame in flight per page (a page
//      still busy with an older frame gets the newest one when it says it is ready; the frames in
//      between are skipped for it);
//   2. each page decodes them off screen and says "ready N";
//   3. when every page *in the barrier* is ready, every ready page is told "show N" at once and
//      draws it on its next display refresh. A page of the barrier that is not ready by the
//      deadline (the round's start + timeout) leaves it, and the others are told without it.
// A page that keeps the others waiting leaves it too: one ready more than both twice the
// stream's frame interval (the median of the last frames' intervals) and three times the median
// of the other pages after the round began, for kSlowRounds rounds in a row (a page 450 ms slow
// within a 500 ms timeout set the whole wall's pace before), so the others keep the stream's
// rate. It rejoins once it has been ready before the round ended in kSlowRounds rounds in a row.
// A page out of the barrier rejoins by being ready for a round's frame before that round ends. A
// page that is ready only for a frame whose round is over is told to show it at once, alone: its
// display keeps moving, a frame or more behind, until it catches up. A new page starts out of
// the barrier and gets the frame of the round in progress (or the last one shown) at once.
// Frames that complete while a round runs wait for it to end, the newest replacing older ones.
// While no page is in the barrier, a round waits (up to the deadline) for every page.
//
// No sockets and no clock of its own: the caller passes the time, carries out the Actions, and
// calls expire() at the deadline(). Not thread-safe (the web thread owns it).
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

namespace voxwall::walls {

class SwapBarrier {
 public:
  using Clock = std::chrono::steady_clock;
  using Page = std::uint64_t;

  // What the caller must do now, in this order.
  struct Actions {
    std::vector<std::pair<Page, std::uint64_t>> send;  // give page P frame F's segments
    std::vector<Page> left;  // left the barrier: not ready by the deadline
    struct Slow {
      Page page;
      double readyMs, othersMs, intervalMs;  // its last round: its ready time, the others' median
    };
    std::vector<Slow> slowed;  // left the barrier: slower than the others and the stream
    std::vector<Page> joined;  // joined (or rejoined) the barrier
    std::vector<std::pair<Page, std::uint64_t>> show;  // tell page P to show frame F now
    // Rounds that ended: frame F was shown together on these pages (possibly none).
    std::vector<std::pair<std::uint64_t, std::vector<Page>>> swapped;
    std::vector<std::uint64_t> skipped;  // frames replaced by a newer one before their round
  };

  static constexpr int kSlowRounds = 3;

  explicit SwapBarrier(std::chrono::milliseconds timeout);

  Actions add(Page page, Clock::time_point now);
  Actions remove(Page page, Clock::time_point now);
  // A new complete frame (ids increase).
  Actions offer(std::uint64_t frame, Clock::time_point now);
  // `page` has decoded `frame` and can show it.
  Actions ready(Page page, std::uint64_t frame, Clock::time_point now);
  // Ends the round in progress when its deadline has passed.
  Actions expire(Clock::time_point now);

  // When expire() has something to do; nullopt when no round runs.
  std::optional<Clock::time_point> deadline() const;
  // The frames whose segments may still be sent: the round's, the one waiting for a round, and
  // the last one shown (for pages that join). The caller may forget every other frame.
  std::vector<std::uint64_t> framesInUse() const;
  bool member(Page page) const;
  std::size_t pages() const { return pages_.size(); }
  std::size_t members() const;

 private:
  struct PageState {
    bool member = false;
    bool outForSlowness = false;            // left as slow: rejoins after kSlowRounds in time
    int slowRounds = 0;                     // slow rounds in a row (a member)
    int inTime = 0;                         // rounds in a row it was ready in (out for slowness)
    std::optional<std::uint64_t> inFlight;  // sent, not yet said ready
    std::optional<std::uint64_t> sent;      // the newest frame it was given
  };
  struct Round {
    std::uint64_t frame = 0;
    Clock::time_point started, deadline;
    std::set<Page> waiting;  // pages of the barrier not yet ready
    std::set<Page> ready;
    std::map<Page, double> readyMs;  // members' ready times after the round began
  };
  // A page that said ready for the round's frame in time: shown with the others; joins.
  void readyInTime(Page page, PageState& p, Clock::time_point now, Actions& a);
  // At a round's end: members slower than the others and the stream leave (kSlowRounds).
  void judgeSlowness(const Round& r, Actions& a);
  // The median of the last frames' intervals, in ms; nullopt before three.
  std::optional<double> streamIntervalMs() const;
  // The frame a page should be working on now.
  std::optional<std::uint64_t> target() const;
  void pump(Page page, Actions& a);
  void start(std::uint64_t frame, Clock::time_point now, Actions& a);
  void finish(Clock::time_point now, Actions& a);

  std::chrono::milliseconds timeout_;
  std::map<Page, PageState> pages_;
  std::optional<Round> round_;
  std::optional<std::uint64_t> queued_, lastShown_;
  std::optional<Clock::time_point> lastOffer_;
  std::vector<double> intervalsMs_;  // the last frames' intervals (at most 9), oldest first
};

}  // namespace voxwall::walls
