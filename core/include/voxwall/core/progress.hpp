// Progress reporting for long offline work (encoders, readers of big files).
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

namespace voxwall {

// Receives "done of total" updates for a named stage. Thread-safe: encoders call advance()
// from worker threads; the callback runs under a lock, at most about 200 times per stage.
class Progress {
 public:
  using Callback =
      std::function<void(const std::string& stage, std::uint64_t done, std::uint64_t total)>;
  Progress() = default;
  explicit Progress(Callback cb) : cb_(std::move(cb)) {}

  void begin(std::string stage, std::uint64_t total);
  // Put before every later stage's name (e.g. "step 3/64: " while a series is encoded).
  void setPrefix(std::string prefix);
  std::string prefix();
  void advance(std::uint64_t n = 1);
  void end();

 private:
  Callback cb_;
  std::mutex mutex_;
  std::string stage_, prefix_;
  std::uint64_t total_ = 0;
  std::uint64_t done_ = 0;
  std::uint64_t lastReported_ = 0;
};

}  // namespace voxwall
