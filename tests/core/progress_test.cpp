#include <gtest/gtest.h>

#include <thread>
#include <vector>
#include <voxwall/core/progress.hpp>

using voxwall::Progress;

TEST(Progress, ReportsStartEndAndBoundedUpdatesFromManyThreads) {
  std::vector<std::pair<std::uint64_t, std::uint64_t>> calls;
  Progress p([&](const std::string& stage, std::uint64_t done, std::uint64_t total) {
    EXPECT_EQ(stage, "work");
    calls.emplace_back(done, total);
  });
  p.begin("work", 100000);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (int i = 0; i < 25000; ++i) p.advance();
    });
  for (auto& t : threads) t.join();
  p.end();
  ASSERT_GE(calls.size(), 2u);
  EXPECT_EQ(calls.front(), std::make_pair(std::uint64_t(0), std::uint64_t(100000)));
  EXPECT_EQ(calls.back(), std::make_pair(std::uint64_t(100000), std::uint64_t(100000)));
  EXPECT_LE(calls.size(), 203u);  // about 200 updates at most, however many advance() calls
  for (std::size_t i = 1; i < calls.size(); ++i) EXPECT_GE(calls[i].first, calls[i - 1].first);
}
