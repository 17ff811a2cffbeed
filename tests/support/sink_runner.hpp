// A wall sink serving on its own thread for tests (link voxwall::walls), with its log kept.
#pragma once

#include <chrono>
#include <mutex>
#include <string>
#include <thread>
#include <vector>
#include <voxwall/walls/sink.hpp>

#include "wait_until.hpp"

namespace voxwall::test {

// Two 20x10 displays side by side with a 4-pixel gap: a 44x10 virtual screen.
inline walls::Wall twoDisplayWall() {
  return walls::parseWall(R"({"wall": "t2x1", "display": {"width": 20, "height": 10},
                              "bezel_px": {"x": 4, "y": 0}, "grid": {"columns": 2, "rows": 1}})",
                          "test");
}

// Settings of a sink for that wall on a free loopback port, writing to `outDir` if given.
inline walls::SinkSettings twoDisplaySink(const std::string& outDir = "") {
  walls::SinkSettings s;
  s.wall = twoDisplayWall();
  s.outDir = outDir;
  return s;
}

class SinkRunner {
 public:
  explicit SinkRunner(walls::SinkSettings settings)
      : sink_(std::move(settings), [this](const std::string& line) {
          std::lock_guard lock(mutex_);
          log_.push_back(line);
        }) {
    thread_ = std::thread([this] { sink_.run(); });
  }
  ~SinkRunner() { stop(); }
  // Stops the sink (it frees its port) and waits for its thread; idempotent.
  void stop() {
    if (!thread_.joinable()) return;
    sink_.stop();
    thread_.join();
  }
  walls::Sink& sink() { return sink_; }
  std::uint16_t port() const { return sink_.port(); }
  std::string log() {
    std::lock_guard lock(mutex_);
    std::string all;
    for (const auto& line : log_) all += line + "\n";
    return all;
  }
  // Waits up to 10 s until `done(stats)` holds.
  template <typename F>
  bool waitFor(F done) {
    return waitUntil([&] { return done(sink_.stats()); });
  }
  // Waits up to 10 s until the log holds `text`.
  bool waitForLog(const std::string& text) {
    return waitUntil([&] { return log().find(text) != std::string::npos; });
  }

 private:
  walls::Sink sink_;
  std::thread thread_;
  std::mutex mutex_;
  std::vector<std::string> log_;
};

}  // namespace voxwall::test
