// Lines an outsider can cause (refusals, drops, connections, refused frames), told at most
// `burst` times every 10 s per kind, with how many were not told since: a flood of connections or
// of refused frames must not flood the log, while an operator's few connections are all told.
#pragma once

#include <chrono>
#include <map>
#include <string>

namespace voxwall::walls {

class LogThrottle {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr std::chrono::seconds kWindow{10};

  explicit LogThrottle(int burst = 1) : burst_(burst) {}

  // One more event of `kind`, described by `what`: the line to log ("what", then "what (and 283
  // more like it since the last such line)"), or empty when it is only counted. Kinds are fixed
  // words or bounded by the wall (a display's name), never by what a peer sends.
  std::string line(const std::string& kind, const std::string& what,
                   Clock::time_point now = Clock::now()) {
    Kind& k = kinds_[kind];
    if (k.told == 0 || now - k.windowStart >= kWindow) k.windowStart = now, k.told = 0;
    if (k.told >= burst_) {
      ++k.untold;
      return {};
    }
    std::string out = what;
    if (k.untold)
      out += " (and " + std::to_string(k.untold) + " more like it since the last such line)";
    ++k.told, k.untold = 0;
    return out;
  }

 private:
  struct Kind {
    Clock::time_point windowStart{};
    int told = 0;  // lines told in the window that began at windowStart
    long untold = 0;
  };
  int burst_;
  std::map<std::string, Kind> kinds_;
};

}  // namespace voxwall::walls
