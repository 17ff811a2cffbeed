// The shared file of decode tables (host_tables.hpp): a part is made once, by one process, and
// read by every process attached to its slot; a slot's pages go when the last detaches; another
// key never reads a slot in use; a file that is not the one named is refused; two processes make
// one range grid together, each a share of its tasks, and both get the grid made alone.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/host_tables.hpp>

using namespace voxwall::codec;

namespace {

// The file is this process's for the test only.
class HostTables : public ::testing::Test {
 protected:
  void SetUp() override { peer_ = hosttables::create(); }
  void TearDown() override { hosttables::leave(); }
  hosttables::Peer peer_;
};

void fill(std::uint8_t* p, std::size_t n, std::uint8_t v) { std::memset(p, v, n); }

TEST_F(HostTables, APartIsMadeOnceAndEveryAttachedViewReadsIt) {
  constexpr std::uint64_t kKey = 77, kBytes = 3 << 20;
  const auto before = hosttables::counts();
  auto a = hosttables::Region::attach(kKey, 4, kBytes);
  auto b = hosttables::Region::attach(kKey, 4, kBytes);
  ASSERT_TRUE(a && b);
  int made = 0;
  EXPECT_TRUE(a->makeOnce(2, [&] { fill(a->data() + (1 << 20), 1 << 20, 9), ++made; }));
  EXPECT_FALSE(b->makeOnce(2, [&] { fill(b->data() + (1 << 20), 1 << 20, 5), ++made; }));
  EXPECT_EQ(made, 1);
  EXPECT_EQ(b->data()[(1 << 20) + 12345], 9);  // b's mapping sees what a made
  EXPECT_EQ(b->data()[12345], 0);              // part 0 was never made
  const auto after = hosttables::counts();
  EXPECT_EQ(after.made - before.made, 1u);
  EXPECT_EQ(after.found - before.found, 1u);

  // Another key whose slot is the same (4096 slots) is refused while the slot is in use.
  EXPECT_EQ(hosttables::Region::attach(kKey + 4096, 4, kBytes), nullptr);
  // So are the same key with other sizes.
  EXPECT_EQ(hosttables::Region::attach(kKey, 5, kBytes), nullptr);

  // When the last view detaches the pages go: a later view finds the part to be made again.
  a.reset();
  EXPECT_EQ(b->data()[(1 << 20) + 7], 9);  // b is still attached
  b.reset();
  auto c = hosttables::Region::attach(kKey + 4096, 4, kBytes);  // the slot is free again
  ASSERT_TRUE(c);
  EXPECT_EQ(c->data()[(1 << 20) + 7], 0);
  EXPECT_TRUE(c->makeOnce(2, [&] { fill(c->data() + (1 << 20), 1 << 20, 3); }));
}

TEST_F(HostTables, AThrowingMakeLeavesThePartToBeMadeByTheNextCall) {
  auto a = hosttables::Region::attach(5, 1, 4096);
  ASSERT_TRUE(a);
  EXPECT_THROW(a->makeOnce(0, [] { throw std::runtime_error("out of memory"); }),
               std::runtime_error);
  EXPECT_TRUE(a->makeOnce(0, [&] { a->data()[0] = 1; }));
}

TEST_F(HostTables, TablesOverASlotAreNotShared) {
  EXPECT_EQ(hosttables::Region::attach(1, 1, std::uint64_t(1) << 36), nullptr);
}

TEST_F(HostTables, WithoutAFileNothingIsShared) {
  hosttables::leave();
  EXPECT_FALSE(hosttables::active());
  EXPECT_EQ(hosttables::Region::attach(1, 1, 4096), nullptr);
}

// Another process joins the file through /proc, makes a part and exits; this process finds it
// made. The part outlives the process that made it while this one stays attached.
TEST_F(HostTables, AnotherProcessJoinsTheFileAndMakesAPartThisOneReads) {
  auto mine = hosttables::Region::attach(42, 2, 8192);
  ASSERT_TRUE(mine);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    hosttables::leave();  // the child's copy of this process's descriptor, forgotten
    if (!hosttables::join(peer_).empty()) _exit(2);
    auto r = hosttables::Region::attach(42, 2, 8192);
    if (!r) _exit(3);
    const bool made = r->makeOnce(1, [&] { fill(r->data() + 4096, 4096, 0xab); });
    _exit(made ? 0 : 4);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << "2: join failed, 3: attach failed, 4: found it made";
  int made = 0;
  EXPECT_FALSE(mine->makeOnce(1, [&] { ++made; }));
  EXPECT_EQ(made, 0);
  EXPECT_EQ(mine->data()[4096 + 100], 0xab);
}

// Under a file-size limit (ulimit -f) the file is not made (sizing it would end the process with
// SIGXFSZ): create() says why, and the process goes on.
TEST(HostTablesLimits, AFileSizeLimitIsSaidNotFatal) {
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    rlimit limit{1 << 20, 1 << 20};
    if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(2);
    try {
      hosttables::create();
    } catch (const std::system_error& e) {
      _exit(std::string(e.what()).find("ulimit -f") != std::string::npos ? 0 : 3);
    }
    _exit(4);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status)) << "ended by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "3: another error, 4: no error";
}

TEST_F(HostTables, AFileThatIsNotTheOneNamedIsRefused) {
  hosttables::Peer wrongInode = peer_;
  ++wrongInode.inode;
  EXPECT_NE(hosttables::join(wrongInode), "");
  hosttables::Peer notAMemfd = peer_;
  notAMemfd.fd = 0;  // standard input: not the shared tables' file
  EXPECT_NE(hosttables::join(notAMemfd), "");
  hosttables::Peer gone = peer_;
  gone.fd = 1 << 20;  // no such descriptor
  EXPECT_NE(hosttables::join(gone), "");
}

// A volume's voxels as its decoder would give them, a brick row (z0 .. z1) at a time.
float voxel(int x, int y, int z) { return float((x * 7 + y * 13 + z * 29) % 251); }

RangeGrid gridOf(glm::ivec3 dims, const std::function<void()>& beforeFill = {}) {
  return slabRangeGrid(
      dims, ScalarType::UInt8, 4, 8, std::size_t(1) << 16,
      [&](int y0, int y1, int z0, int z1, auto&& slice) {
        if (beforeFill) beforeFill();
        for (int z = z0; z <= z1; ++z)
          for (int y = y0; y <= y1; ++y)
            for (int x = 0; x < dims.x; ++x)
              slice(z)[std::size_t(y - y0) * std::size_t(dims.x) + std::size_t(x)] = voxel(x, y, z);
      });
}

// Waits (with a deadline) for a byte on `fd`; false if none came.
bool awaitByte(int fd) {
  pollfd p{fd, POLLIN, 0};
  char c;
  return poll(&p, 1, 60000) == 1 && read(fd, &c, 1) == 1;
}

TEST_F(HostTables, TwoProcessesMakeOneRangeGridTogether) {
  const glm::ivec3 dims{64, 96, 128};
  const RangeGrid alone = gridOf(dims);  // no RangeShare: made alone
  const hosttables::RangeShare share(0xfeed);
  ASSERT_EQ(hosttables::rangeShareKey(), 0xfeedu);
  // Each process's first fill waits until the other has made its first: both are then attached
  // and each holds a task, so neither makes the whole grid before the other begins.
  int toChild[2], toParent[2], counts[2];
  ASSERT_EQ(pipe(toChild), 0);
  ASSERT_EQ(pipe(toParent), 0);
  ASSERT_EQ(pipe(counts), 0);
  const auto meet = [](int send, int receive) {
    return [send, receive, once = std::make_shared<std::once_flag>()] {
      std::call_once(*once, [&] {
        if (write(send, "x", 1) != 1 || !awaitByte(receive))
          throw std::runtime_error("the other process did not come");
      });
    };
  };
  const auto before = hosttables::counts();
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    int code = 1;
    try {
      const RangeGrid together = gridOf(dims, meet(toParent[1], toChild[0]));
      const auto after = hosttables::counts();
      const std::uint64_t mine[2] = {after.made - before.made, after.found - before.found};
      code = together == alone && write(counts[1], mine, sizeof mine) == sizeof mine ? 0 : 3;
    } catch (...) {
      code = 2;
    }
    _exit(code);
  }
  const RangeGrid together = gridOf(dims, meet(toChild[1], toParent[0]));
  const auto after = hosttables::counts();
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0)
      << "2: the child did not meet this process, 3: its grid differs";
  EXPECT_TRUE(together == alone);
  std::uint64_t theirs[2] = {};
  ASSERT_EQ(read(counts[0], theirs, sizeof theirs), ssize_t(sizeof theirs));
  const std::uint64_t made = after.made - before.made, found = after.found - before.found;
  // Every task was made by exactly one of the two, and each made some.
  EXPECT_EQ(made + found, theirs[0] + theirs[1]);
  EXPECT_EQ(made + theirs[0], made + found);
  EXPECT_GT(made, 0u);
  EXPECT_GT(theirs[0], 0u);
  for (int fd : {toChild[0], toChild[1], toParent[0], toParent[1], counts[0], counts[1]}) close(fd);
}

TEST_F(HostTables, WithoutAFileARangeGridIsMadeAlone) {
  hosttables::leave();
  const hosttables::RangeShare share(0xfeed);
  EXPECT_EQ(hosttables::rangeShareKey(), 0u);
  const auto before = hosttables::counts();
  const RangeGrid g = gridOf({20, 20, 20});
  EXPECT_EQ(hosttables::counts().made, before.made);
  EXPECT_TRUE(g == gridOf({20, 20, 20}));
}

}  // namespace
