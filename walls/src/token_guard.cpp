#include <algorithm>
#include <cstdint>
#include <voxwall/core/text.hpp>
#include <voxwall/walls/token_guard.hpp>

namespace voxwall::walls {

bool sameSecret(const std::string& a, const std::string& b) {
  unsigned diff = unsigned(a.size() != b.size());
  const std::size_t n = std::max(a.size(), b.size());
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= unsigned(x ^ y);
  }
  return diff == 0;
}

TokenGuard::Result TokenGuard::check(const std::string& address, const std::string& token,
                                     Clock::time_point now) {
  if (token_.empty()) return {};
  auto it = guesses_.find(address);
  if (it != guesses_.end() && now < it->second.until) {
    // Backing off: not even a right token is looked at.
    ++it->second.untold;
    return {Verdict::BackingOff, ""};
  }
  if (sameSecret(token, token_)) {
    if (it != guesses_.end()) guesses_.erase(it);
    return {};
  }
  // A bounded table: forget addresses whose back-off has passed, then the oldest entry.
  if (it == guesses_.end() && guesses_.size() >= 4096) {
    std::erase_if(guesses_, [&](const auto& g) { return g.second.until < now; });
    if (guesses_.size() >= 4096) guesses_.erase(guesses_.begin());
  }
  Guesses& g = guesses_[address];
  ++g.wrong;
  const auto backoff = std::min<Clock::duration>(
      kFirstBackoff * (std::int64_t(1) << std::min(g.wrong - 1, 20)), kMaxBackoff);
  g.until = now + backoff;
  Result result{Verdict::Wrong, ""};
  // One line for the first wrong tokens, then at most one every 10 s with the count since.
  if (g.wrong <= 3 || now - g.told >= std::chrono::seconds(10)) {
    const double seconds = std::chrono::duration<double>(backoff).count();
    result.logLine = "wrong token (" + std::to_string(g.wrong) + " from " + address +
                     (g.untold ? ", " + std::to_string(g.untold) + " more refused unheard" : "") +
                     "; refused unheard for " + formatLine("%.1f", seconds) + " s)";
    g.told = now, g.untold = 0;
  } else {
    ++g.untold;
  }
  return result;
}

}  // namespace voxwall::walls
