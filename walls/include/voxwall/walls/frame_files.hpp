// A presented frame on disk, all or nothing: every display's picture
// (frame_NNNNN_<display>.png or .jpg, and frame_NNNNN_mosaic.png for the whole virtual screen)
// is decoded from the frame's segments, encoded (the pictures in parallel) and written under a
// temporary name first, then all are renamed into place, and last the frame's marker
// frame_NNNNN.done (JSON: each file's size and xxHash64) is written. A frame without its marker
// is not complete: a sink killed while writing leaves at most such files, and
// removeIncompleteFrames() clears them when the next sink starts on the folder.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/image.hpp>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/wall.hpp>

namespace voxwall::walls {

std::string frameStem(std::uint64_t frame);  // "frame_00012"
std::string frameMarkerPath(const std::string& dir, std::uint64_t frame);

enum class FrameFormat { Png, Jpeg };

struct FrameFileSettings {
  bool mosaic = false;  // also the whole virtual screen, bezels included
  FrameFormat format = FrameFormat::Png;
  voxwall::ImageEncoding encoding;  // PNG level, JPEG quality
  int threads = 0;                  // pictures decoded and encoded at once (0: all cores)
};

// A frame whose segments do not decode (a corrupt body behind a good header): its files are not
// written, and later frames may well be.
class UndecodableFrame : public FormatError {
  using FormatError::FormatError;
};

// ".png" or ".jpg".
const char* frameFileExtension(FrameFormat format);

// Writes one frame as above. Throws UndecodableFrame for a segment that does not decode, and
// FormatError naming the file and the reason when a file cannot be written (e.g. "No space left
// on device"); nothing of the frame stays under a final name then.
void writeFrameFiles(const std::string& dir, const Wall& wall, const AssembledFrame& frame,
                     const FrameFileSettings& settings);

// Writes presented frames to a folder on a thread of its own, in order, so that files never hold
// the wall back: at most `queue` frames wait (held as their segments, about a megabyte for a
// bigeye frame); a frame that comes to a full queue pushes the oldest waiting one out, which is
// not written. Once a frame cannot be written (a full disk: every later frame would fail the same
// way), the writer takes no more frames. Each frame's outcome goes to `events` on the writer's
// thread (skips on the pushing thread). `job` is the caller's, handed back.
class FrameFileWriter {
 public:
  enum class Outcome { Written, Skipped, Failed };
  using Events = std::function<void(std::uint64_t job, std::uint64_t frame, Outcome outcome,
                                    const std::string& why)>;
  FrameFileWriter(std::string dir, Wall wall, FrameFileSettings settings, int queue, Events events);
  // Finishes the frames already queued, then ends the thread.
  ~FrameFileWriter();
  // Queues a frame; returns at once. Thread-safe.
  void push(std::uint64_t job, std::shared_ptr<const AssembledFrame> frame);
  // Waits until every queued frame was written (or skipped, or the writer failed).
  void drain();

 private:
  void run();
  std::string dir_;
  Wall wall_;
  FrameFileSettings settings_;
  std::size_t queue_;
  Events events_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::pair<std::uint64_t, std::shared_ptr<const AssembledFrame>>> waiting_;
  bool busy_ = false, failed_ = false, stop_ = false;
  std::thread thread_;
};

// Whether the frame's marker is there and every file it lists has its recorded size and hash.
bool frameFilesComplete(const std::string& dir, std::uint64_t frame);

// Removes temporaries (".tmp.") and the pictures of frames without a marker. Returns how many
// files it removed.
int removeIncompleteFrames(const std::string& dir);

}  // namespace voxwall::walls
