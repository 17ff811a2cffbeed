// Waiting in tests on a condition, never for a fixed time: polls `done` until it holds or the
// deadline passes (a deadline, not a timing assertion: a busy machine only waits longer). The
// one poll interval of the tests lives here; a test that waits calls this, not a sleep loop of
// its own.
#pragma once

#include <chrono>
#include <functional>
#include <thread>

namespace voxwall::test {

inline bool waitUntil(const std::function<bool()>& done,
                      std::chrono::milliseconds deadline = std::chrono::seconds(10)) {
  const auto end = std::chrono::steady_clock::now() + deadline;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return done();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // the poll interval
  }
  return true;
}

}  // namespace voxwall::test
