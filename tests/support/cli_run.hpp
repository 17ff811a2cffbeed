// The voxwall program run as a user runs it (VOXWALL_BINARY, set by the test's CMake target), and
// the one-line error contract.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <string>

namespace voxwall {

struct CliRun {
  int status = -1;
  std::string out;  // stdout and stderr together
};

// voxwall behind `prefix` (e.g. "prlimit --data=N ").
inline CliRun runLimited(const std::string& prefix, const std::string& args) {
  CliRun r;
  const std::string cmd = prefix + std::string(VOXWALL_BINARY) + " " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

// The error contract: exit status 1 and exactly one line "voxwall: <file>: ...".
inline void expectOneLineError(const CliRun& r, const std::string& prefix) {
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_EQ(r.out.rfind(prefix, 0), 0u) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
}

inline CliRun runVoxwall(const std::string& args) { return runLimited("", args); }

}  // namespace voxwall
