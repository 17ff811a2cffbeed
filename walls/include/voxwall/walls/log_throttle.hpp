// Refusals the sink's log tells at most once every 10 s per kind, with how many it did not tell
// since: a flood of connections or of refused frames must not flood the log.
#pragma once

#include <chrono>
#include <map>
#include <string>

namespace voxwall::walls {

class LogThrottle {
 public:
  using Clock = std::chrono::steady_clock;
  // One more event of `kind`, described by `what`: the line to log ("what", then "what (and 283
  // more like it since the last such line)"), or empty when it is only counted.
  std::string line(const std::string& kind, const std::string& what,
                   Clock::time_point now = Clock::now()) {
    Kind& k = kinds_[kind];
    if (k.told != Clock::time_point{} && now - k.told < std::chrono::seconds(10)) {
      ++k.untold;
      return {};
    }
    std::string out = what;
    if (k.untold)
      out += " (and " + std::to_string(k.untold) + " more like it since the last such line)";
    k.told = now, k.untold = 0;
    return out;
  }

 private:
  struct Kind {
    Clock::time_point told{};
    long untold = 0;
  };
  std::map<std::string, Kind> kinds_;  // a handful of fixed kinds
};

}  // namespace voxwall::walls
