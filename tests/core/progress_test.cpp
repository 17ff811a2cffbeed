#include <gtest/gtest.h>

#include <string>
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

// A prefix goes before every later stage's name until it is changed; prefix() gives it back, so
// a caller can add to the prefix it was given and restore it after.
TEST(Progress, APrefixNamesLaterStagesAndCanBeRestored) {
  std::vector<std::string> stages;
  Progress p([&](const std::string& stage, std::uint64_t, std::uint64_t) {
    if (stages.empty() || stages.back() != stage) stages.push_back(stage);
  });
  p.setPrefix("step 1/2: ");
  const std::string outer = p.prefix();
  EXPECT_EQ(outer, "step 1/2: ");
  p.setPrefix(outer + "blocks of 4^3: ");
  p.begin("coding", 1);
  p.end();
  p.setPrefix(outer);
  p.begin("measuring", 1);
  p.end();
  EXPECT_EQ(stages,
            (std::vector<std::string>{"step 1/2: blocks of 4^3: coding", "step 1/2: measuring"}));
}
