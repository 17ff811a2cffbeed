// The shared file of tables (host_tables.hpp): a memfd of 4096 sparse slots of 64 GiB. A slot
// starts with a page of header (a lock word, the processes attached, the key and sizes of the
// tables in it), then a state word a part (free, being made, made), then the tables. Only pages
// something wrote are resident.
#include <fcntl.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <mutex>
#include <system_error>
#include <thread>
#include <voxwall/codec/host_tables.hpp>

namespace voxwall::codec::hosttables {

namespace {

constexpr char kName[] = "voxwall-tables";
constexpr int kSlotShift = 36;  // 64 GiB a slot
constexpr std::uint64_t kSlots = 4096;
constexpr std::uint64_t kPage = 4096;
constexpr std::uint32_t kFree = 0, kMaking = 1, kMade = 2;

struct Header {
  std::uint32_t lock;   // 0 free, 1 held (atomic_ref)
  std::uint32_t users;  // processes attached
  std::uint64_t key, parts, bytes;
};

std::uint64_t pageUp(std::uint64_t n) { return (n + kPage - 1) / kPage * kPage; }

std::atomic<std::uint64_t> madeCount{0}, foundCount{0};

// A wait for another process: yields first (it is usually a fraction of a millisecond), then
// sleeps a little at a time so that a long wait costs no core.
void pause(int& round) {
  if (++round < 64)
    sched_yield();
  else
    std::this_thread::sleep_for(std::chrono::microseconds(50));
}

class SlotLock {
 public:
  explicit SlotLock(Header& h) : lock_(h.lock) {
    int round = 0;
    for (;;) {
      std::uint32_t expected = 0;
      if (lock_.compare_exchange_weak(expected, 1, std::memory_order_acquire)) return;
      pause(round);
    }
  }
  ~SlotLock() { lock_.store(0, std::memory_order_release); }
  SlotLock(const SlotLock&) = delete;
  SlotLock& operator=(const SlotLock&) = delete;

 private:
  std::atomic_ref<std::uint32_t> lock_;
};

}  // namespace

struct SharedFile {
  int fd = -1;
  explicit SharedFile(int f) : fd(f) {}
  ~SharedFile() { close(fd); }
  SharedFile(const SharedFile&) = delete;
  SharedFile& operator=(const SharedFile&) = delete;
};

namespace {
std::mutex currentLock;
std::shared_ptr<SharedFile> current;
}  // namespace

Peer create() {
  // Sizing a file past the process's file-size limit (ulimit -f) would send it SIGXFSZ, which
  // ends it: such a process makes its tables alone.
  rlimit limit{};
  if (getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY &&
      limit.rlim_cur < (kSlots << kSlotShift))
    throw std::system_error(EFBIG, std::generic_category(),
                            "the file-size limit (ulimit -f) is below the shared tables' file's");
  const int fd = memfd_create(kName, MFD_CLOEXEC);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "memfd_create");
  struct stat st {};
  if (ftruncate(fd, off_t(kSlots << kSlotShift)) != 0 || fstat(fd, &st) != 0) {
    const int e = errno;
    close(fd);
    throw std::system_error(e, std::generic_category(), "sizing the shared tables' file");
  }
  std::lock_guard lock(currentLock);
  current = std::make_shared<SharedFile>(fd);
  return {std::int64_t(getpid()), fd, std::uint64_t(st.st_ino)};
}

std::string join(const Peer& peer) {
  const std::string path = "/proc/" + std::to_string(peer.pid) + "/fd/" + std::to_string(peer.fd);
  char link[256] = {};
  const ssize_t n = readlink(path.c_str(), link, sizeof link - 1);
  if (n < 0) return path + ": " + std::strerror(errno);
  if (std::string(link, std::size_t(n)).rfind(std::string("/memfd:") + kName, 0) != 0)
    return path + " is " + std::string(link, std::size_t(n)) + ", not the shared tables' file";
  const int fd = open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) return path + ": " + std::strerror(errno);
  struct stat st {};
  if (fstat(fd, &st) != 0 || std::uint64_t(st.st_ino) != peer.inode) {
    close(fd);
    return path + " is another file than the one process " + std::to_string(peer.pid) + " made";
  }
  std::lock_guard lock(currentLock);
  current = std::make_shared<SharedFile>(fd);
  return {};
}

bool active() {
  std::lock_guard lock(currentLock);
  return current != nullptr;
}

void leave() {
  std::lock_guard lock(currentLock);
  current.reset();
}

Counts counts() {
  return {madeCount.load(std::memory_order_relaxed), foundCount.load(std::memory_order_relaxed)};
}

std::unique_ptr<Region> Region::attach(std::uint64_t key, std::uint64_t parts,
                                       std::uint64_t bytes) {
  std::shared_ptr<SharedFile> file;
  {
    std::lock_guard lock(currentLock);
    file = current;
  }
  if (!file) return nullptr;
  const std::uint64_t dataAt = kPage + pageUp(parts * 4);
  const std::uint64_t mapBytes = dataAt + pageUp(std::max<std::uint64_t>(bytes, 1));
  if (mapBytes > (std::uint64_t(1) << kSlotShift)) return nullptr;
  const std::uint64_t slotAt = (key % kSlots) << kSlotShift;
  void* m = mmap(nullptr, mapBytes, PROT_READ | PROT_WRITE, MAP_SHARED, file->fd, off_t(slotAt));
  if (m == MAP_FAILED) return nullptr;
  auto* map = static_cast<std::uint8_t*>(m);
  auto& header = *reinterpret_cast<Header*>(map);
  bool taken = false;  // by another set of tables now: this one is made privately
  {
    SlotLock lock(header);
    if (header.users == 0) header.key = key, header.parts = parts, header.bytes = bytes;
    taken = header.key != key || header.parts != parts || header.bytes != bytes;
    if (!taken) ++header.users;
  }
  if (taken) {
    munmap(map, mapBytes);
    return nullptr;
  }
  std::unique_ptr<Region> r(new Region);
  r->file_ = std::move(file);
  r->map_ = map, r->mapBytes_ = mapBytes, r->slotAt_ = slotAt;
  r->states_ = reinterpret_cast<std::uint32_t*>(map + kPage);
  r->data_ = map + dataAt;
  return r;
}

Region::~Region() {
  auto& header = *reinterpret_cast<Header*>(map_);
  {
    SlotLock lock(header);
    if (--header.users == 0)  // nobody reads the tables now: their pages go (they read as zeros)
      fallocate(file_->fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, off_t(slotAt_ + kPage),
                off_t(mapBytes_ - kPage));
  }
  munmap(map_, mapBytes_);
}

bool Region::tryMake(std::uint64_t i, const std::function<void()>& make) const {
  std::atomic_ref<std::uint32_t> state(states_[i]);
  std::uint32_t v = kFree;
  if (!state.compare_exchange_strong(v, kMaking, std::memory_order_acq_rel)) return false;
  try {
    make();
  } catch (...) {
    state.store(kFree, std::memory_order_release);
    throw;
  }
  state.store(kMade, std::memory_order_release);
  madeCount.fetch_add(1, std::memory_order_relaxed);
  return true;
}

bool Region::makeOnce(std::uint64_t i, const std::function<void()>& make) const {
  std::atomic_ref<std::uint32_t> state(states_[i]);
  for (int round = 0;; pause(round)) {  // while another process (or thread) makes it
    if (state.load(std::memory_order_acquire) == kMade) {
      foundCount.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    if (tryMake(i, make)) return true;
  }
}

namespace {
thread_local std::uint64_t rangeKey = 0;
}  // namespace

RangeShare::RangeShare(std::uint64_t key) : previous_(rangeKey) { rangeKey = key; }
RangeShare::~RangeShare() { rangeKey = previous_; }

std::uint64_t rangeShareKey() { return rangeKey != 0 && active() ? rangeKey : 0; }

int hostCores() {
  const long n = sysconf(_SC_NPROCESSORS_ONLN);
  return n > 0 ? int(n) : 1;
}

}  // namespace voxwall::codec::hosttables
