// The frames a render job writes to --out (frame_output.cpp): the job manifest, --resume's
// choice of frames to keep, and the writer thread. Private to voxwall_master; prepareOutput(job)
// and framePath() are declared for everyone in <voxwall/master/render_job.hpp>.
#pragma once

#include <chrono>
#include <future>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/master/render_job.hpp>

namespace voxwall::master {

// Seconds from `t` to now on the steady clock.
inline double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// Writes frames in a background thread, one at a time: push() waits for the previous frame.
// After each frame is in place, its size and hash go into the job manifest (written atomically),
// so --resume keeps exactly the frames that were finished.
class FrameWriter {
 public:
  FrameWriter(std::string outDir, nlohmann::json manifest);
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;
  ~FrameWriter();
  // Returns the seconds spent waiting for the previous write.
  double push(voxwall::Image image, std::string path, std::optional<glm::dvec3> background);
  // Waits for the write in flight (rethrowing its error); returns the wait.
  double finish();
  double totalWriteSeconds() const { return totalWriteSeconds_; }

 private:
  std::string outDir_;
  nlohmann::json manifest_;  // touched by the one write in flight, or after finish()
  std::future<double> pending_;
  double totalWriteSeconds_ = 0;
};

// prepareOutput(job), also giving the manifest as written (the frame writer adds to it).
std::vector<bool> prepareOutput(const JobSettings& job, nlohmann::json* manifest);

}  // namespace voxwall::master
