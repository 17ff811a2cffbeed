// Text for people: byte counts and printf-style report lines, shared by the codecs' reports, the
// commands and the sink.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace voxwall {

// A byte count for people: "512 B", "7.7 MiB" (binary units up to TiB).
std::string humanBytes(double bytes);

// A deadline for people: "300 ms", "5 s" (whole seconds when it is a whole number of them).
std::string durationText(int ms);

// printf-style formatting of a report line (at most 511 characters; longer lines are cut).
template <class... Args>
std::string formatLine(const char* format, Args... args) {
  char line[512];
  std::snprintf(line, sizeof line, format, args...);
  return line;
}

// Text from outside (a peer's wall id, a viewer's command, a Host header) made safe for a log line
// or a terminal: in double quotes, printable ASCII kept, a quote or backslash escaped, any other
// byte (newline, ESC, NUL, 8-bit) written as \xNN, and cut after `maxChars` input bytes with
// "..." and the full length. Nothing from outside reaches a log any other way.
std::string quotedForLog(std::string_view text, std::size_t maxChars = 80);

}  // namespace voxwall
