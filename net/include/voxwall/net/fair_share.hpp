// Which held place a newcomer takes when a pool of connections is full.
//
// Places already held (the display pages, or the viewers, of a sink's web view: past the token
// where there is one, else as they came): the places go to the displays, then to the addresses,
// as evenly as the newcomer can make them. A newcomer replaces the oldest place of the most
// crowded display when that display holds at least two more places than the newcomer's; failing
// that, the oldest place of the address that holds the most of the newcomer's display when it
// holds at least two more there than the newcomer's address. Otherwise it is refused. So pages
// crowding one display cannot keep another display's page out, one address cannot keep out
// another (each gets its share however many places the first opens), and a wall's pages through
// one SSH tunnel (all from 127.0.0.1) still get one place per display.
// Viewers are all one group (display -1).
#pragma once

#include <algorithm>
#include <cstddef>
#include <map>
#include <span>
#include <string>
#include <utility>

namespace voxwall::net {

struct HeldPlace {
  int group = -1;       // a page's display index; -1 for every viewer
  std::string address;  // the remote address, without the port
};

// The index in `held` (oldest first) of the place a newcomer of `group` from `address` takes, or
// -1 when it is refused.
inline int fairShareVictim(std::span<const HeldPlace> held, int group, const std::string& address) {
  std::map<int, int> perGroup;
  for (const auto& h : held) ++perGroup[h.group];
  const auto crowded = std::max_element(perGroup.begin(), perGroup.end(),
                                        [](auto& a, auto& b) { return a.second < b.second; });
  int target = -1;
  if (crowded != perGroup.end() && crowded->second >= perGroup[group] + 2) target = crowded->first;
  // Within the chosen display (or the newcomer's): the address holding the most of it.
  const int within = target >= 0 ? target : group;
  std::map<std::string, int> perAddress;
  for (const auto& h : held)
    if (h.group == within) ++perAddress[h.address];
  const auto most = std::max_element(perAddress.begin(), perAddress.end(),
                                     [](auto& a, auto& b) { return a.second < b.second; });
  if (most == perAddress.end()) return -1;
  if (target < 0 && most->second < perAddress[address] + 2) return -1;
  for (std::size_t i = 0; i < held.size(); ++i)
    if (held[i].group == within && held[i].address == most->first) return int(i);
  return -1;
}

// Pools of connections none of which has proven itself (HTTP requests in flight, WebSockets
// waiting for their token, tile-port connections that have not said Hello): the newcomer always
// comes in, in place of the oldest connection of the address holding the most, so a flood from
// a few addresses replaces its own first and what proves itself quickly (a rank's Hello, a
// page's token) is through before its turn comes. The index in `held` (oldest first), or -1 when
// it is empty. `group` is not looked at.
inline int oldestOfCrowd(std::span<const HeldPlace> held) {
  std::map<std::string, int> perAddress;
  for (const auto& h : held) ++perAddress[h.address];
  const auto most = std::max_element(perAddress.begin(), perAddress.end(),
                                     [](auto& a, auto& b) { return a.second < b.second; });
  if (most == perAddress.end()) return -1;
  for (std::size_t i = 0; i < held.size(); ++i)
    if (held[i].address == most->first) return int(i);
  return -1;
}

}  // namespace voxwall::net
