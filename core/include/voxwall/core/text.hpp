// Text for people: byte counts and printf-style report lines, shared by the codecs' reports, the
// commands and the sink.
#pragma once

#include <cstdio>
#include <string>

namespace voxwall {

// A byte count for people: "512 B", "7.7 MiB" (binary units up to TiB).
std::string humanBytes(double bytes);

// printf-style formatting of a report line (at most 511 characters; longer lines are cut).
template <class... Args>
std::string formatLine(const char* format, Args... args) {
  char line[512];
  std::snprintf(line, sizeof line, format, args...);
  return line;
}

}  // namespace voxwall
