#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <voxwall/core/process.hpp>

// Touching 64 MiB shows in the resident size and in the peak, which never falls below it.
TEST(Process, MemoryFollowsWhatThisProcessTouches) {
  const auto before = voxwall::processMemory();
  ASSERT_GT(before.residentBytes, 0u) << "no /proc/self/status";
  EXPECT_GE(before.peakBytes, before.residentBytes);
  constexpr std::size_t kBytes = std::size_t(64) << 20;
  const auto block = std::make_unique<char[]>(kBytes);
  std::memset(block.get(), 1, kBytes);
  const auto after = voxwall::processMemory();
  EXPECT_GE(after.residentBytes, before.residentBytes + kBytes / 2);
  EXPECT_GE(after.peakBytes, after.residentBytes);
  EXPECT_EQ(block[kBytes - 1], 1);
}
