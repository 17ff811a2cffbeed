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

 private:
  Region() = default;
  std::shared_ptr<SharedFile> file_;
  std::uint8_t* map_ = nullptr;
  std::uint64_t mapBytes_ = 0, slotAt_ = 0;
  std::uint32_t* states_ = nullptr;  // read and written as std::atomic_ref
  std::uint8_t* data_ = nullptr;
};

}  // namespace voxwall::codec::hosttables
