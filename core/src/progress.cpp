#include <algorithm>
#include <voxwall/core/progress.hpp>

namespace voxwall {

void Progress::begin(std::string stage, std::uint64_t total) {
  std::lock_guard lock(mutex_);
  stage_ = prefix_ + stage;
  total_ = total;
  done_ = lastReported_ = 0;
  if (cb_) cb_(stage_, 0, total_);
}

void Progress::setPrefix(std::string prefix) {
  std::lock_guard lock(mutex_);
  prefix_ = std::move(prefix);
}

std::string Progress::prefix() {
  std::lock_guard lock(mutex_);
  return prefix_;
}

void Progress::advance(std::uint64_t n) {
  std::lock_guard lock(mutex_);
  done_ += n;
  if (cb_ && (done_ - lastReported_) * 200 >= std::max<std::uint64_t>(total_, 1)) {
    lastReported_ = done_;
    cb_(stage_, std::min(done_, total_), total_);
  }
}

void Progress::end() {
  std::lock_guard lock(mutex_);
  if (cb_ && lastReported_ != total_) cb_(stage_, total_, total_);
  lastReported_ = total_;
}

}  // namespace voxwall
