// The displays' swap barrier without sockets or clocks: pages switch together, a page that never
// answers leaves after the timeout and the others go on, a late page rejoins, frames that come
// during a round wait (the newest wins), and a page has one frame in flight.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <voxwall/walls/swap_barrier.hpp>

using namespace voxwall;
using walls::SwapBarrier;
using namespace std::chrono_literals;

namespace {

using Sent = std::vector<std::pair<SwapBarrier::Page, std::uint64_t>>;

bool sentTo(const SwapBarrier::Actions& a, SwapBarrier::Page page, std::uint64_t frame) {
  return std::find(a.send.begin(), a.send.end(), std::pair{page, frame}) != a.send.end();
}
bool shownTo(const SwapBarrier::Actions& a, SwapBarrier::Page page, std::uint64_t frame) {
  return std::find(a.show.begin(), a.show.end(), std::pair{page, frame}) != a.show.end();
}

// Three pages, all in the barrier after frame 1 was shown on each.
struct ThreePages {
  SwapBarrier barrier{500ms};
  SwapBarrier::Clock::time_point t0{};
  ThreePages() {
    for (SwapBarrier::Page p : {1, 2, 3}) barrier.add(p, t0);
    barrier.offer(1, t0);
    for (SwapBarrier::Page p : {1, 2, 3}) barrier.ready(p, 1, t0 + 10ms);
  }
};

}  // namespace

TEST(SwapBarrier, EveryPageIsToldToShowAFrameOnlyWhenAllAreReady) {
  SwapBarrier barrier(500ms);
  const SwapBarrier::Clock::time_point t0{};
  barrier.add(1, t0);
  barrier.add(2, t0);
  const auto offered = barrier.offer(7, t0);
  EXPECT_TRUE(sentTo(offered, 1, 7));
  EXPECT_TRUE(sentTo(offered, 2, 7));
  EXPECT_TRUE(barrier.deadline().has_value());
  const auto first = barrier.ready(1, 7, t0 + 5ms);
  EXPECT_TRUE(first.show.empty());  // page 2 is not ready yet
  const auto second = barrier.ready(2, 7, t0 + 8ms);
  EXPECT_TRUE(shownTo(second, 1, 7));
  EXPECT_TRUE(shownTo(second, 2, 7));
  ASSERT_EQ(second.swapped.size(), 1u);
  EXPECT_EQ(second.swapped[0].first, 7u);
  EXPECT_EQ(second.swapped[0].second.size(), 2u);
  EXPECT_EQ(barrier.members(), 2u);
  EXPECT_FALSE(barrier.deadline().has_value());
}

TEST(SwapBarrier, APageThatNeverAnswersLeavesAfterTheTimeoutAndTheOthersGoOn) {
  ThreePages w;
  ASSERT_EQ(w.barrier.members(), 3u);
  const auto t = w.t0 + 1s;
  w.barrier.offer(2, t);
  w.barrier.ready(1, 2, t + 10ms);
  const auto two = w.barrier.ready(2, 2, t + 12ms);
  EXPECT_TRUE(two.show.empty());  // page 3 is still in the barrier and not ready
  EXPECT_TRUE(w.barrier.expire(t + 499ms).show.empty());  // not yet its deadline
  const auto expired = w.barrier.expire(t + 500ms);
  EXPECT_EQ(expired.left, (std::vector<SwapBarrier::Page>{3}));
  EXPECT_TRUE(shownTo(expired, 1, 2));
  EXPECT_TRUE(shownTo(expired, 2, 2));
  EXPECT_FALSE(shownTo(expired, 3, 2));
  EXPECT_FALSE(w.barrier.member(3));
  // The next frame does not wait for page 3 (which still has frame 2 in flight: it gets nothing).
  const auto next = w.barrier.offer(3, t + 600ms);
  EXPECT_FALSE(sentTo(next, 3, 3));
  w.barrier.ready(1, 3, t + 610ms);
  const auto shown = w.barrier.ready(2, 3, t + 612ms);
  EXPECT_TRUE(shownTo(shown, 1, 3));
  EXPECT_TRUE(shownTo(shown, 2, 3));
}

TEST(SwapBarrier, ALatePageIsShownItsFrameAloneAndRejoinsWhenItKeepsUp) {
  ThreePages w;
  const auto t = w.t0 + 1s;
  w.barrier.offer(2, t);
  w.barrier.ready(1, 2, t + 10ms);
  w.barrier.ready(2, 2, t + 10ms);
  w.barrier.expire(t + 500ms);  // page 3 leaves
  w.barrier.offer(3, t + 510ms);
  // Page 3 is ready for frame 2 at last: it shows frame 2 alone and gets frame 3 at once.
  const auto late = w.barrier.ready(3, 2, t + 700ms);
  EXPECT_TRUE(shownTo(late, 3, 2));
  EXPECT_TRUE(sentTo(late, 3, 3));
  EXPECT_TRUE(late.joined.empty());
  // Ready for frame 3 before its round ends: in the barrier again, shown with the others.
  w.barrier.ready(1, 3, t + 710ms);
  const auto joined = w.barrier.ready(3, 3, t + 720ms);
  EXPECT_EQ(joined.joined, (std::vector<SwapBarrier::Page>{3}));
  const auto shown = w.barrier.ready(2, 3, t + 730ms);
  EXPECT_TRUE(shownTo(shown, 1, 3));
  EXPECT_TRUE(shownTo(shown, 2, 3));
  EXPECT_TRUE(shownTo(shown, 3, 3));
  EXPECT_EQ(w.barrier.members(), 3u);
}

TEST(SwapBarrier, FramesDuringARoundWaitAndTheNewestWins) {
  ThreePages w;
  const auto t = w.t0 + 1s;
  w.barrier.offer(2, t);
  EXPECT_TRUE(w.barrier.offer(3, t + 1ms).send.empty());  // waits for round 2
  const auto replaced = w.barrier.offer(4, t + 2ms);
  EXPECT_EQ(replaced.skipped, (std::vector<std::uint64_t>{3}));
  w.barrier.ready(1, 2, t + 10ms);
  w.barrier.ready(2, 2, t + 10ms);
  const auto end = w.barrier.ready(3, 2, t + 10ms);
  // Round 2 ends and round 4 starts in the same step: shows before the next frame's segments.
  EXPECT_TRUE(shownTo(end, 3, 2));
  EXPECT_TRUE(sentTo(end, 1, 4));
  EXPECT_TRUE(sentTo(end, 3, 4));
  const auto inUse = w.barrier.framesInUse();
  EXPECT_NE(std::find(inUse.begin(), inUse.end(), 4u), inUse.end());
  EXPECT_EQ(std::find(inUse.begin(), inUse.end(), 3u), inUse.end());
}

TEST(SwapBarrier, ANewPageGetsTheNewestFrameAtOnceWithoutHoldingTheOthers) {
  ThreePages w;
  const auto t = w.t0 + 1s;
  const auto added = w.barrier.add(9, t);
  EXPECT_TRUE(sentTo(added, 9, 1));  // the frame the wall shows
  EXPECT_FALSE(w.barrier.member(9));
  const auto alone = w.barrier.ready(9, 1, t + 30ms);
  EXPECT_TRUE(shownTo(alone, 9, 1));
  // A round does not wait for it; being ready in time puts it in the barrier.
  w.barrier.offer(2, t + 100ms);
  w.barrier.ready(9, 2, t + 105ms);
  EXPECT_TRUE(w.barrier.member(9));
  for (SwapBarrier::Page p : {1, 2}) w.barrier.ready(p, 2, t + 110ms);
  const auto shown = w.barrier.ready(3, 2, t + 110ms);
  EXPECT_TRUE(shownTo(shown, 9, 2));
}

TEST(SwapBarrier, ClosingTheLastPageAWaitsForEndsTheRound) {
  ThreePages w;
  const auto t = w.t0 + 1s;
  w.barrier.offer(2, t);
  w.barrier.ready(1, 2, t + 1ms);
  w.barrier.ready(2, 2, t + 1ms);
  const auto closed = w.barrier.remove(3, t + 2ms);
  EXPECT_TRUE(shownTo(closed, 1, 2));
  EXPECT_TRUE(shownTo(closed, 2, 2));
  EXPECT_EQ(w.barrier.pages(), 2u);
}

TEST(SwapBarrier, ReadyForAFrameAPageWasNotGivenIsIgnored) {
  ThreePages w;
  const auto t = w.t0 + 1s;
  w.barrier.offer(2, t);
  EXPECT_TRUE(w.barrier.ready(1, 5, t + 1ms).show.empty());
  EXPECT_TRUE(w.barrier.ready(42, 2, t + 1ms).show.empty());  // no such page
  w.barrier.ready(1, 2, t + 2ms);
  w.barrier.ready(2, 2, t + 2ms);
  EXPECT_EQ(w.barrier.ready(3, 2, t + 2ms).show.size(), 3u);
}

TEST(SwapBarrier, WithNoPageInTheBarrierARoundWaitsForEveryPage) {
  SwapBarrier barrier(500ms);
  const SwapBarrier::Clock::time_point t0{};
  barrier.add(1, t0);
  barrier.add(2, t0);
  barrier.offer(1, t0);
  EXPECT_TRUE(barrier.ready(1, 1, t0 + 1ms).show.empty());  // page 2 is waited for too
  const auto expired = barrier.expire(t0 + 500ms);
  EXPECT_TRUE(shownTo(expired, 1, 1));
  EXPECT_TRUE(expired.left.empty());  // page 2 was never in the barrier
  EXPECT_TRUE(barrier.member(1));
  EXPECT_FALSE(barrier.member(2));
  EXPECT_THROW(SwapBarrier(0ms), std::invalid_argument);
}

namespace {

// Eleven fast pages (ready 5 ms after they are given a frame) and page 1, ready `slowMs` after,
// until `fastFromMs` (then 5 ms too), on a stream of a frame every 33 ms for 5 s, on the
// barrier's clock (500 ms timeout). What came of it.
struct Simulated {
  int together = 0;                         // rounds every fast page showed together
  int offeredAfter = 0, togetherAfter = 0;  // frames offered, rounds together, once page 1 left
  int slowShown = 0;                        // frames page 1 was told to show
  int slowed = 0;                           // times page 1 left for slowness
  int rejoined = 0;                         // times page 1 joined after that
  bool slowInLastRound = false;
};

Simulated simulate(int slowMs, int fastFromMs = 1 << 30) {
  SwapBarrier barrier(500ms);
  const SwapBarrier::Clock::time_point t0{};
  std::multimap<int, std::pair<SwapBarrier::Page, std::uint64_t>> due;  // ms -> ready
  Simulated out;
  auto apply = [&](const SwapBarrier::Actions& a, int ms) {
    for (const auto& [page, frame] : a.send)
      due.emplace(ms + (page == 1 && ms < fastFromMs ? slowMs : 5), std::pair{page, frame});
    for (const auto& [frame, shown] : a.swapped) {
      const auto fast = std::count_if(shown.begin(), shown.end(), [](auto p) { return p != 1; });
      out.together += fast == 11;
      out.togetherAfter += fast == 11 && out.slowed > 0;
      out.slowInLastRound = std::count(shown.begin(), shown.end(), 1) > 0;
    }
    for (const auto& [page, frame] : a.show) out.slowShown += page == 1;
    for (const auto& s : a.slowed) out.slowed += s.page == 1;
    for (const auto page : a.joined) out.rejoined += page == 1 && out.slowed > 0;
  };
  for (SwapBarrier::Page p = 1; p <= 12; ++p) apply(barrier.add(p, t0), 0);
  for (int ms = 0; ms <= 5000; ++ms) {
    const auto now = t0 + std::chrono::milliseconds(ms);
    if (ms % 33 == 0) {
      out.offeredAfter += out.slowed > 0;
      apply(barrier.offer(std::uint64_t(ms / 33 + 1), now), ms);
    }
    while (!due.empty() && due.begin()->first <= ms) {
      const auto [page, frame] = due.begin()->second;
      due.erase(due.begin());
      apply(barrier.ready(page, frame, now), ms);
    }
    if (const auto d = barrier.deadline(); d && *d <= now) apply(barrier.expire(now), ms);
  }
  return out;
}

}  // namespace

// A page ready 450 ms (or 200 ms) after each frame stays inside the 500 ms timeout, and it set
// the whole wall's pace: 11 pages switched about 11 times in 5 s on a stream of 152 frames (25
// at 200 ms). It now leaves the barrier after three slow rounds and is shown frames alone; the
// others keep the stream's rate from then on (a round for every frame offered but the one in
// progress when it left).
TEST(SwapBarrier, ASlowPageLeavesTheBarrierAndTheOthersKeepTheStreamsRate) {
  for (const int slowMs : {450, 200}) {
    const auto s = simulate(slowMs);
    EXPECT_EQ(s.slowed, 1) << slowMs;
    EXPECT_GE(s.togetherAfter, s.offeredAfter - 1) << slowMs;
    EXPECT_GE(s.offeredAfter, 90) << slowMs;                     // it left within 2 s
    EXPECT_GE(s.slowShown, 5000 / (slowMs + 33) - 3) << slowMs;  // it keeps moving, behind
    EXPECT_EQ(s.rejoined, 0) << slowMs;
  }
  // A page slower than the others but well within the stream's interval is not judged slow.
  const auto modest = simulate(20);
  EXPECT_EQ(modest.slowed, 0);
  EXPECT_GE(modest.together, 150);
}

TEST(SwapBarrier, ASlowPageThatKeepsUpAgainRejoins) {
  const auto s = simulate(450, 2000);
  EXPECT_EQ(s.slowed, 1);
  EXPECT_EQ(s.rejoined, 1);
  EXPECT_TRUE(s.slowInLastRound);
  EXPECT_GE(s.togetherAfter, s.offeredAfter - 1);
}

// A page that closes after it said ready, before the round ends, is not judged (its time was
// kept for the judgement: a crash of the web thread's round before).
TEST(SwapBarrier, APageThatClosesAfterItWasReadyIsForgotten) {
  SwapBarrier barrier(500ms);
  const SwapBarrier::Clock::time_point t0{};
  for (SwapBarrier::Page p : {1, 2, 3}) barrier.add(p, t0);
  std::uint64_t frame = 1;
  auto t = t0;
  // Three rounds to make every page a member and give the stream an interval.
  for (; frame <= 4; ++frame, t += 33ms) {
    barrier.offer(frame, t);
    for (SwapBarrier::Page p : {1, 2, 3}) barrier.ready(p, frame, t + 5ms);
  }
  barrier.offer(frame, t);
  barrier.ready(1, frame, t + 5ms);
  barrier.ready(2, frame, t + 6ms);
  barrier.remove(1, t + 7ms);
  SwapBarrier::Actions a;
  EXPECT_NO_THROW(a = barrier.ready(3, frame, t + 8ms));
  ASSERT_EQ(a.swapped.size(), 1u);
  EXPECT_EQ(a.swapped[0].second.size(), 2u);
}
