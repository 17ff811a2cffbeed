// `voxwall sink`'s options and what they mean: the command line as a plain struct, and a pure
// function from it to the sink's settings (unit-tested in tests/master/sink_settings_test.cpp).
// The orchestration (signals, stdin, the summary line) is in sink.cpp.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>
#include <voxwall/walls/sink.hpp>

namespace voxwall::cli {

struct SinkOptions {
  std::string wall, listen = "127.0.0.1:7400", out, outFormat = "png", token, http;
  std::vector<std::string> httpOrigins;
  int surface = 0, frames = 0, pending = 16, maxPeers = 256, helloTimeoutMs = 5000;
  int maxViewers = 64, maxDisplayPages = 0, swapTimeoutMs = 500, writeQueue = 8;
  int swapLeadMs = 25;
  double peerIdle = 30;
  double jobIdle = 300;
  std::uint64_t pendingMiB = 0;
  bool mosaic = false, quiet = false, noStdin = false;
};

// Registers every sink option with `cmd`.
void addSinkOptions(CLI::App& cmd, SinkOptions& o);

// The sink's settings: reads the wall file and picks the surface; checks every value. Throws
// std::invalid_argument naming the option, FormatError for the wall file.
walls::SinkSettings sinkSettings(const SinkOptions& o);

}  // namespace voxwall::cli
