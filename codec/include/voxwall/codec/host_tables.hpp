// Tables a codec makes from its file to decode (tvq's associated codebooks), made once per host
// instead of once per rank: the ranks of a job on one host hold one file of shared memory (a
// memfd, so the system frees it when the last of them exits, however it exits), and each set of
// tables has a slot in it, found from a key the ranks compute alike from the file's bytes. The
// first process that needs a part of a slot makes it; the others wait for it and read it. A slot's
// pages go back to the system when the last process using it detaches.
//
// The shared pages count in each process's Pss_Shmem (its share), not in RssAnon (its private
// memory): core/process.hpp reads both.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace voxwall::codec::hosttables {

// How another process on this host opens this process's shared file.
struct Peer {
  std::int64_t pid = 0;
  int fd = -1;
  std::uint64_t inode = 0;
};

// Makes an empty shared file (sparse: nothing resident) this process's and returns how the
// others open it. Throws std::system_error where the system cannot make one.
Peer create();
// Opens the shared file another process on this host made (/proc/PID/fd/FD, checked to be that
// file) and makes it this process's. Returns an empty string, or why it cannot (the process is
// gone, /proc hides it, it is another file): then this process has no shared file.
std::string join(const Peer& peer);
// Whether this process has a shared file. leave() forgets it (regions attached stay valid).
bool active();
void leave();

// What this process did with the slots' parts since it started: made them, or found them made.
struct Counts {
  std::uint64_t made = 0, found = 0;
};
Counts counts();

struct SharedFile;  // this process's descriptor of the shared file

// A slot of the shared file: `parts` state words and `bytes` of tables, zero until made.
class Region {
 public:
  // Null where this process has no shared file, the tables are over a slot's size (64 GiB), or
  // another set of tables (another key) holds the key's slot now.
  static std::unique_ptr<Region> attach(std::uint64_t key, std::uint64_t parts,
                                        std::uint64_t bytes);
  ~Region();  // the last process to detach gives the slot's pages back
  Region(const Region&) = delete;
  Region& operator=(const Region&) = delete;
  std::uint8_t* data() const { return data_; }
  // Runs `make` (which fills part i's bytes) unless a process has or is doing so, in which case
  // it waits until part i is made. Returns whether this call made it. If `make` throws, the part
  // stays to be made and the exception goes on.
  bool makeOnce(std::uint64_t i, const std::function<void()>& make) const;
  // Runs `make` if no process has taken part i yet; returns whether it did (false: another
  // process made it, is making it, or gave it up while this call looked). No wait.
  bool tryMake(std::uint64_t i, const std::function<void()>& make) const;

 private:
  Region() = default;
  std::shared_ptr<SharedFile> file_;
  std::uint8_t* map_ = nullptr;
  std::uint64_t mapBytes_ = 0, slotAt_ = 0;
  std::uint32_t* states_ = nullptr;  // read and written as std::atomic_ref
  std::uint8_t* data_ = nullptr;
};

// Value ranges made together (codec/brick_volume.hpp's slabRangeGrid): while a RangeShare lives
// on a thread, a range grid that thread makes is made with the other processes on the host that
// make the grid of the same key at the same time. Each takes the tasks no process has taken, then
// the others' cells from the shared file: each rank makes its share of the ranges instead of all
// of them. The key names what the ranges are of (the sections' bytes, the step, the render
// flags); 0, or no shared file: alone.
class RangeShare {
 public:
  explicit RangeShare(std::uint64_t key);
  ~RangeShare();
  RangeShare(const RangeShare&) = delete;
  RangeShare& operator=(const RangeShare&) = delete;

 private:
  std::uint64_t previous_;
};
// This thread's RangeShare key (0: none, or no shared file).
std::uint64_t rangeShareKey();
// `key` with `v` mixed in (splitmix64's finalizer over their sum): a key that also names how
// the tables are laid out.
inline std::uint64_t mixKey(std::uint64_t key, std::uint64_t v) {
  std::uint64_t z = key + 0x9e3779b97f4a7c15ull + v;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  z ^= z >> 31;
  return z ? z : 1;
}
// The cores of this host (not only those this process may use): what the processes sharing a
// grid split its work by, so that they split it alike.
int hostCores();

}  // namespace voxwall::codec::hosttables
