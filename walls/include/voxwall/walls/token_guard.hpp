// The token check of the sink's two doors (the tile port, sink_core.hpp, and the web view's
// WebSockets, web_view.hpp), with a back-off per remote address: after a wrong token the address
// is refused unheard (even with the right token) for 0.1 s, doubling with each further wrong one
// up to 30 s, so guessing gains nothing from speed; the log gets the first three wrong tokens of
// an address, then at most one line every 10 s with how many were refused since.
#pragma once

#include <chrono>
#include <map>
#include <string>

namespace voxwall::walls {

// Compares secrets in time that depends on their lengths only.
bool sameSecret(const std::string& a, const std::string& b);

class TokenGuard {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr std::chrono::milliseconds kFirstBackoff{100};
  static constexpr std::chrono::seconds kMaxBackoff{30};

  enum class Verdict { Accepted, Wrong, BackingOff };
  struct Result {
    Verdict verdict = Verdict::Accepted;
    // For a wrong token that the log should tell: "wrong token (7 from 10.0.0.5, 212 more
    // refused unheard; refused unheard for 6.4 s)"; empty otherwise.
    std::string logLine;
  };

  // `token` empty: every attempt is accepted.
  explicit TokenGuard(std::string token) : token_(std::move(token)) {}
  // One attempt with `token` from `address`. Not thread-safe.
  Result check(const std::string& address, const std::string& token, Clock::time_point now);
  Result check(const std::string& address, const std::string& token) {
    return check(address, token, Clock::now());
  }

 private:
  // Wrong tokens of one address: how many, until when it is refused unheard, how many refusals
  // the log has not told yet, and when it last told one.
  struct Guesses {
    int wrong = 0, untold = 0;
    Clock::time_point until{}, told{};
  };
  std::string token_;
  std::map<std::string, Guesses> guesses_;  // at most 4096 addresses
};

}  // namespace voxwall::walls
