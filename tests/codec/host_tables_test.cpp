// The shared file of decode tables (host_tables.hpp): a part is made once, by one process, and
// read by every process attached to its slot; a slot's pages go when the last detaches; another
// key never reads a slot in use; a file that is not the one named is refused.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <stdexcept>
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

}  // namespace
