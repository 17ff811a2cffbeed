#include <gtest/gtest.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <memory>
#include <thread>
#include <voxwall/core/parallel.hpp>
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
  // Memory of its own is private; a file it maps and reads is the mapped files' part.
  EXPECT_GE(after.privateBytes, before.privateBytes + kBytes / 2);
  EXPECT_LE(after.privateBytes + after.fileBytes, after.residentBytes + (1u << 20));
}

// Reading a mapped file raises the mapped files' part, not the private one.
TEST(Process, AMappedFileReadIsNotPrivateMemory) {
  char path[] = "/tmp/voxwall-process-XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  constexpr std::size_t kBytes = std::size_t(32) << 20;
  ASSERT_EQ(ftruncate(fd, off_t(kBytes)), 0);
  {
    // Written through a mapping of its own, then dropped: the file's pages are in the page cache.
    void* w = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    ASSERT_NE(w, MAP_FAILED);
    std::memset(w, 3, kBytes);
    munmap(w, kBytes);
  }
  const auto before = voxwall::processMemory();
  void* m = mmap(nullptr, kBytes, PROT_READ, MAP_SHARED, fd, 0);
  ASSERT_NE(m, MAP_FAILED);
  const auto* bytes = static_cast<const volatile unsigned char*>(m);
  unsigned sum = 0;
  for (std::size_t i = 0; i < kBytes; i += 4096) sum += bytes[i];
  const auto after = voxwall::processMemory();
  munmap(m, kBytes);
  close(fd);
  unlink(path);
  EXPECT_EQ(sum, 3u * unsigned(kBytes / 4096));
  EXPECT_GE(after.fileBytes, before.fileBytes + kBytes / 2);
  EXPECT_LT(after.privateBytes, before.privateBytes + kBytes / 4);
}

// Shared memory this process writes (what the ranks on a host share) is its share of shared
// memory, all of it while no other process maps it, and not private memory.
TEST(Process, SharedMemoryIsItsShareNotPrivate) {
  const int fd = memfd_create("voxwall-process-test", MFD_CLOEXEC);
  ASSERT_GE(fd, 0);
  constexpr std::size_t kBytes = std::size_t(32) << 20;
  ASSERT_EQ(ftruncate(fd, off_t(kBytes)), 0);
  const auto before = voxwall::processMemory();
  void* m = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  ASSERT_NE(m, MAP_FAILED);
  std::memset(m, 5, kBytes);
  const auto after = voxwall::processMemory();
  munmap(m, kBytes);
  close(fd);
  if (before.sharedBytes == 0 && after.sharedBytes == 0)
    GTEST_SKIP() << "/proc/self/smaps_rollup has no Pss_Shmem here";
  EXPECT_GE(after.sharedBytes, before.sharedBytes + kBytes / 2);
  EXPECT_LT(after.privateBytes, before.privateBytes + kBytes / 4);
}

// A block freed in a thread goes back to the system at once, even after a larger block freed
// before it raised glibc's own threshold (without the setting, the second block stays resident
// in the thread's heap: this test failed so).
TEST(Process, LargeBlocksFreedInAThreadLeaveNothingResident) {
#if defined(__SANITIZE_ADDRESS__) || !defined(__GLIBC__)
  GTEST_SKIP() << "glibc's allocator only (AddressSanitizer keeps freed blocks in quarantine)";
#endif
  voxwall::mapLargeBlocksAlone();
  auto touch = [](std::size_t bytes) {
    char* p = static_cast<char*>(std::malloc(bytes));
    ASSERT_NE(p, nullptr);
    std::memset(p, 1, bytes);
    asm volatile("" : : "r"(p) : "memory");
    std::free(p);
  };
  const auto before = voxwall::processMemory();
  std::thread([&] {
    touch(std::size_t(24) << 20);  // mapped: it raises glibc's threshold to its size
    touch(std::size_t(20) << 20);  // under that threshold: from the thread's heap
  }).join();
  const auto after = voxwall::processMemory();
  EXPECT_GE(after.peakBytes, before.residentBytes + (std::size_t(20) << 20));
  EXPECT_LT(after.residentBytes, before.residentBytes + (std::size_t(4) << 20));
}

// Work for the next frame runs on a thread that gives way (nice 19), and the threads it starts
// inherit that; the caller's own priority is untouched.
TEST(Process, AThreadThatYieldsCoresRunsAtTheLeastPriorityAndSoDoItsThreads) {
  const int mine = getpriority(PRIO_PROCESS, id_t(gettid()));
  int yielded = -100, started = -100;
  std::thread([&] {
    voxwall::yieldCoresToOthers();
    yielded = getpriority(PRIO_PROCESS, id_t(gettid()));
    std::thread([&] { started = getpriority(PRIO_PROCESS, id_t(gettid())); }).join();
  }).join();
  EXPECT_EQ(yielded, 19);
  EXPECT_EQ(started, 19);
  EXPECT_EQ(getpriority(PRIO_PROCESS, id_t(gettid())), mine);
}
