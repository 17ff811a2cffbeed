// A minimal parallel loop over an index range, shared by encoders and the CPU raycaster.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#ifdef __linux__
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>
#endif
#include <vector>

namespace voxwall {

// Number of worker threads to use when the user asked for `requested` (0 = all cores).
// Cores this process may run on: its CPU affinity mask (set by taskset, cgroups, or an MPI
// launcher that binds ranks to cores), else all of the machine's.
inline int usableCores() {
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) return std::max(1, CPU_COUNT(&set));
#endif
  return int(std::max(1u, std::thread::hardware_concurrency()));
}

inline int resolveThreads(int requested) {
  if (requested > 0) return requested;
  return usableCores();
}

// Lowers the calling thread to the least CPU priority (nice 19; on Linux a thread's own, and the
// threads it starts inherit it), for work that should take only the cores other work leaves: the
// ranks of one host must not slow each other's frames with work for the next one. Without
// privilege it cannot be raised again, so call it on a thread of its own that then ends.
inline void yieldCoresToOthers() {
#ifdef __linux__
  (void)setpriority(PRIO_PROCESS, id_t(gettid()), 19);
#endif
}

// Calls fn(i) for every i in [0, count) on `threads` threads, handing out indices dynamically.
// The first exception thrown by fn is rethrown on the caller after all workers stop.
template <class Fn>
void parallelFor(std::size_t count, int threads, Fn&& fn) {
  threads =
      std::max(1, std::min<int>(resolveThreads(threads), int(std::max<std::size_t>(count, 1))));
  if (threads == 1) {
    for (std::size_t i = 0; i < count; ++i) fn(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex errorMutex;
  auto worker = [&] {
    for (;;) {
      const std::size_t i = next.fetch_add(1, std::memory_order_relaxed);
      if (i >= count || failed.load(std::memory_order_relaxed)) return;
      try {
        fn(i);
      } catch (...) {
        std::lock_guard lock(errorMutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(std::size_t(threads - 1));
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (auto& th : pool) th.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace voxwall
