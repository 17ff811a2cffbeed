// The distributed frame loop (sort-first): rank 0 picks each frame's camera and screen cut,
// every rank renders its rectangles of the virtual screen from its own copy of the volume, and
// rank 0 assembles the frame, re-balances the cut from the measured costs and writes the frame
// (in a background thread, so frame f is encoded and written while frame f+1 renders).
// Message sequence: master/frame_messages.hpp.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/master/camera_path.hpp>
#include <voxwall/master/communicator.hpp>
#include <voxwall/master/frame_messages.hpp>
#include <voxwall/master/load_balancer.hpp>
#include <voxwall/master/steering.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/net/wire.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::master {

enum class Balance { Static, Dynamic };

// Streaming to a wall sink (walls/sink.hpp): every rendering rank compresses its tiles and sends
// them straight to the sink; rank 0 also holds a control connection for camera commands.
struct StreamSettings {
  std::string host;
  std::uint16_t port = 0;
  std::string token, wallId;
  // The wall's displays (the job's screen is JobSettings' width x height): a sink whose Welcome
  // shows another screen or other displays is refused, and the job fails.
  std::vector<voxwall::Rect> displays;
  glm::dvec3 background{0.0};  // JPEG has no alpha: tiles are composited onto this
  net::TileCodecSettings codec;
  // A job whose tiles have not reached the sink (from every rank that had tiles) for this long
  // fails with NetError, and so does a job that ends without one frame having reached it: a wall
  // that shows nothing is never a success.
  double deadlineSeconds = 30;
};

// Camera changes from the wall, added to the camera path from the frame after they arrive.
struct CameraOffset {
  double azimuthDeg = 0, elevationDeg = 0, zoom = 1, panX = 0, panY = 0;
  node::Orbit apply(node::Orbit orbit) const;
  // Adds a command, kept within reach so that no command winds the camera up: the azimuth
  // offset modulo 360 (in [-180, 180)), the elevation so that `path`'s elevation plus the offset
  // stays within +-90 degrees (straight down or up), the zoom factor within 0.05..20, the pan
  // within +-kMaxPan bounding radii (the volume stays on the screen). Reset clears it.
  void take(const net::Control& command, const node::Orbit& path);
  static constexpr double kMaxPan = 1.5;
};

// Which time step of a series each frame shows (a single volume: step 0 in every frame).
struct TimeSettings {
  int first = 0, last = 0, stride = 1;  // the steps first, first + stride, ... up to last
  // > 0: a job that streams to the wall plays the steps at this many a second (looping), from
  // when the job starts, instead of one a frame; the wall's time commands pause, move and go on.
  double rate = 0;
  int count() const { return (last - first) / stride + 1; }
  // A batch job's frame f of `frames`: the range's f-th step; with more frames than steps each
  // step shows for frames / count() frames (the last one to the end).
  int stepOfFrame(int f, int frames) const;
  // The range's i-th step, i taken modulo count().
  int stepAt(long long i) const;
};

// Which step each frame of a job shows, moved by the wall's time commands (play, pause, step,
// seek). Until a command comes, a job without a rate shows TimeSettings::stepOfFrame (a batch
// job's frames are what the command line says); a job with a rate plays by the clock from its
// start. A command stops that: pause holds the step shown; step N and seek S move to another
// (wrapping around the range; a seek to a step off the stride goes to the nearest in it), which
// the next frame shows; while playing, the position then goes on a step a frame, or by the clock.
class TimePlayer {
 public:
  using Clock = std::chrono::steady_clock;
  // rate: TimeSettings::rate when the job plays by the clock, else 0.
  TimePlayer(const TimeSettings& time, int frames, double rate, Clock::time_point start);
  // Takes a time command; false (and nothing changes) for any other command.
  bool take(const net::Control& command, Clock::time_point now);
  // The step frame f shows (frames are asked for in order, each once).
  int step(int f, Clock::time_point now);
  // The step frame f (after the last step()) is expected to show, for decoding ahead: a batch
  // job's f-th, where no command came; otherwise the step shown last (the clock or the wall
  // moves it).
  int expectedStep(int f) const;
  // Where the player is after the last step(): for the wall's page.
  net::Playback state() const;

 private:
  double clockPosition(Clock::time_point now) const;
  void steer(Clock::time_point now);  // a command came: the position is the wall's from now on
  TimeSettings time_;
  int frames_;
  double rate_;
  bool steered_ = false, playing_ = true, hold_ = false;
  double position_ = 0;  // index into the range (with a rate: at anchor_)
  Clock::time_point anchor_;
  int lastFrame_ = -1, lastIndex_ = 0;
};

struct JobSettings {
  int width = 1920, height = 1080;  // the virtual screen
  int frames = 1;
  CameraPath path;  // default: the default orbit, standing still
  Balance balance = Balance::Dynamic;
  // Static cut: a grid of tiles dealt to the rendering ranks in turn; 0 x 0: one strip per rank.
  int staticTilesX = 0, staticTilesY = 0;
  bool masterRenders = true;  // false: rank 0 only assembles and writes (needs 2+ ranks)
  std::string outDir;         // empty: frames are assembled but not written
  std::string format = "png";
  std::optional<glm::dvec3> background;
  bool resume = false;  // skip frames already complete in outDir
  // Everything that shapes the pixels, as a JSON object; written to outDir/voxwall-job.json and
  // compared on --resume so frames of different renders are never mixed.
  std::string manifest = "{}";
  int watchdogMs = 120000;  // at least this; grows to 4x the slowest frame seen
  BalancerSettings balancer;
  std::optional<StreamSettings> stream;  // none: no wall sink
  // Interactive frames: while camera commands from the wall keep arriving (the last one less than
  // settleSeconds ago), frames are rendered at 1/interactiveStep per side and the sink upsamples
  // them; then full frames follow. Only when streaming without writing frames (a batch job with
  // an output folder never reduces). interactiveStep 1: never.
  int interactiveStep = 4;
  double settleSeconds = 0.5;
  // Once the camera settled, frames at these steps, coarse to full (master/steering.hpp); a
  // camera command arriving during a refining or full frame abandons it.
  std::vector<int> refine = {4, 2, 1};
  double frameBudgetMs = 0;  // > 0: the interactive step keeps a steered frame near this
  TimeSettings time;
  // A transfer function for each step of the volume (`render --range per-step`: each placed on
  // its step's own values); empty: the job's one for every step.
  std::vector<node::TransferFunction> stepTransferFunctions;
  // The clock the job's decisions read: when steered frames settle and when a rank's streamer
  // tries the sink again. Empty: the steady clock. Tests advance their own instead of sleeping;
  // frame times are always measured on the steady clock.
  std::function<std::chrono::steady_clock::time_point()> clock;
};

// The steering of this job (master/steering.hpp): interactive only when it streams to a sink
// and writes no frames (a batch job never reduces, refines or abandons a frame).
SteeringSettings steeringSettings(const JobSettings& job);

struct RankMemory {
  int rank = 0;
  std::string host;
  std::uint64_t residentBytes = 0, peakResidentBytes = 0;
  // Of residentBytes: the rank's own (decoded pages, frame buffers, the heap) and its mapped
  // files' (the .vwz, shared by the ranks on one host; the libraries); and its share of the
  // memory the ranks on its host share (decode tables made once for all of them).
  std::uint64_t privateBytes = 0, fileBytes = 0, sharedBytes = 0;
};

struct FrameSummary {
  int frame = 0;
  double frameSeconds = 0;      // camera decided -> frame handed to the writer, on rank 0
  double renderSeconds = 0;     // the slowest rank's render time
  double gatherSeconds = 0;     // rank 0 waiting for reports after its own render
  double assembleSeconds = 0;   // decoding reports, pasting tiles, balancing
  double writeWaitSeconds = 0;  // waiting for the previous frame's write to finish
  std::vector<int> ranks;       // the rendering ranks
  std::vector<double> rankSeconds;
  std::vector<master::PageStats> rankPages;       // per rendering rank: its decoded pages
  std::vector<RankMemory> rankMemory;             // per rendering rank: its memory after it
  std::vector<std::vector<voxwall::Rect>> rects;  // per rendering rank
  double imbalance = 1;                           // max / mean of rankSeconds
  std::uint64_t samples = 0;
  std::uint64_t rays = 0;    // rays cast by every rank
  int latticeStride = 0;     // the ray lattice's side in pixels (1: a ray a pixel)
  int recuts = 0;            // cut changes so far (dynamic)
  std::string path;          // file the frame goes to, empty when not writing
  std::string streamError;   // the first rank that missed the sink, and why
  int streamedRanks = 0;     // ranks whose tiles reached the sink
  double encodeSeconds = 0;  // the slowest rank's tile compression
  std::uint64_t streamedBytes = 0;
  int controls = 0;  // camera commands from the wall applied to this frame
  // A steered job's first frame: the full frame's time a probe of the view predicted (the
  // screen at 1/16 a side on rank 0, shared among the rendering ranks), which picks the first
  // steered frames' step under the frame budget; 0 otherwise.
  double probeSeconds = 0;
  int step = 1;                                   // > 1: a reduced frame at 1/step per side
  int timeStep = 0;                               // the volume's time step it shows
  net::FramePhase phase = net::FramePhase::Full;  // interactive (steered), refining or full
  bool abandoned = false;              // the camera moved while it rendered: given up, not shown
  std::vector<std::string> sinkNotes;  // what the sink said about earlier frames (drops, refusals)
  // Streaming to a sink: how many of the wall's commands have arrived on rank 0 since this
  // frame took its own; callable until the job ends (a test waits on it before the next frame).
  std::function<std::size_t()> controlsPending;
};

struct JobSummary {
  int framesRendered = 0, framesSkipped = 0;
  double seconds = 0;
  double writeSeconds = 0;             // encoding and writing all frames, in the background thread
  std::vector<RankMemory> memory;      // rank 0 only
  std::vector<std::string> sinkNotes;  // the sink's notes that arrived after the last frame
};

// A rank whose pixels nobody gathers (no frames written: streaming to a sink, or a benchmark)
// renders, encodes and sends `rect` in these bands, one after the other, and keeps one band's
// pixels at a time: rows of bandRows(job) (the tile codec's segment size, so the encoded tiles
// are those of the whole rectangle), top to bottom.
int bandRows(const JobSettings& job);
std::vector<voxwall::Rect> bands(const voxwall::Rect& rect, const JobSettings& job);

// The rectangles of every rank in the first frame (what --dry-run shows). Throws
// std::invalid_argument when the screen cannot be cut for this many ranks.
std::vector<std::vector<voxwall::Rect>> firstFrameRects(const JobSettings& job, int ranks);

// Frames already complete in job.outDir (resume): those the job manifest (voxwall-job.json)
// records with the size and xxHash64 the file still has; any other frame is rendered again
// (with a line on stderr). Checks and rewrites the manifest, removes
// temporaries left by a killed run. Throws FormatError when the directory holds frames of
// different settings. Rank 0 only.
std::vector<bool> prepareOutput(const JobSettings& job);
std::string framePath(const JobSettings& job, int frame);

// Collective: every rank calls this with the same settings. onFrame is called on rank 0 after
// every frame. Throws MpiError (watchdog), FormatError (a corrupt report, a write error) or
// std::invalid_argument; the caller must then abort the job (other ranks may be waiting).
JobSummary runRenderJob(Communicator& comm, node::Backend& backend,
                        const node::RenderVolume& volume, const node::TransferFunction& tf,
                        const node::RenderSettings& render, const JobSettings& job,
                        const std::function<void(const FrameSummary&)>& onFrame = {});

}  // namespace voxwall::master
