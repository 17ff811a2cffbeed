// One rank's renderer: what a rank does with the rectangles a frame gives it. It plans the frame
// (keeping the transfer function's part while the volume and transfer function stay), renders the
// rectangles on its backend, whole or a band at a time, hands each finished part to the caller
// (who compresses and streams it), counts the samples and decoded pages, can be told to give the
// frame up, and applies the rank's memory policy between frames. It knows nothing of MPI, sockets
// or walls: master/ asks it for a frame and streams what it returns.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <future>
#include <optional>
#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/core/process.hpp>
#include <voxwall/core/rect.hpp>
#include <voxwall/node/camera.hpp>
#include <voxwall/node/cost_grid.hpp>
#include <voxwall/node/page_stats.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::node {

// What a frame asks of this rank. The volume and transfer function outlive the call.
struct RankFrame {
  const RenderVolume* volume = nullptr;
  const TransferFunction* tf = nullptr;
  Camera camera;
  int screenWidth = 0, screenHeight = 0;  // the (possibly reduced) virtual screen
  int cellPixels = 32;                    // the cost grid's cell side
  std::vector<Rect> rects;                // this rank's rectangles (may be none)
  // Whole rectangles come back as images (a frame rank 0 writes); otherwise each is rendered and
  // handed on in bands of bandRows rows, and only one band's pixels are held at a time.
  bool keepPixels = true;
  int bandRows = 1024;
  // Polled every few milliseconds on the calling thread while the rank renders (a thread that
  // makes MPI collectives may have to be the one asking): once it says true, the parts not yet
  // rendered are not rendered and the frame comes back abandoned. Empty: never abandoned.
  std::function<bool()> abandoned;
  // Called on the calling thread with each finished part (a band, or a whole rectangle) and the
  // render time so far; returning false stops further calls for this frame (the rest is still
  // rendered: the stream failed, the frame is not).
  std::function<bool(const Rect& part, const Image& pixels, double renderSeconds)> onPart;
};

struct RankFrameResult {
  struct Tile {
    Rect rect;
    Image image;  // empty unless RankFrame::keepPixels
  };
  std::vector<Tile> tiles;  // one per rectangle rendered (all of them unless abandoned)
  CostGrid costs;           // over the whole screen (empty without rectangles)
  double renderSeconds = 0;
  std::uint64_t samples = 0;
  std::uint64_t rays = 0;  // rays cast (fewer than the pixels where the ray lattice interpolates)
  int latticeStride = 0;   // the frame's ray lattice (FramePlan::latticeStride; 0: no rectangle)
  PageStats pages;
  bool abandoned = false;
};

// What rendering a whole screen at full resolution is predicted to cost one rank, from the same
// screen rendered at 1/step a side and scaled by step^2 (RankRenderer::probe).
struct FrameProbe {
  double seconds = 0;
  std::uint64_t samples = 0;
};

// `rect` cut into bands of `rows` rows (at least 1), top to bottom.
std::vector<Rect> rowBands(const Rect& rect, int rows);

// `rects` of a width x height screen mapped onto that screen at 1/step a side (ceil(side / step)),
// edge by edge, so that rectangles that tiled the screen still tile the reduced one; one narrower
// than a step may vanish.
std::vector<Rect> reducedRects(const std::vector<Rect>& rects, int width, int height, int step);

// Not thread-safe: one frame at a time, from one thread.
class RankRenderer {
 public:
  // The backend and settings outlive the renderer.
  RankRenderer(Backend& backend, const RenderSettings& settings);
  ~RankRenderer();
  RankRenderer(const RankRenderer&) = delete;
  RankRenderer& operator=(const RankRenderer&) = delete;

  // Renders the frame's rectangles (after ending any decoding ahead: the pages it decoded count
  // in the result's pages.ahead). Throws what planning and the backend throw.
  RankFrameResult render(const RankFrame& frame);

  // Starts decoding, on the backend's threads, the pages the frame `next` will sample, while
  // this rank waits for it (its task, the other ranks): `next` is rendered at 1/reduce a side
  // over its rectangles (the rank's rectangles of the frame before, at the next camera and time
  // step) and the pixels are dropped. Returns at once; render(), probe() and the destructor end
  // it first (the blocks begun finish, the rest are skipped). Nothing is started after a frame
  // whose rays read no decoded page (raw data, per-ray decoding) or evicted one (the budget does
  // not hold the working set: pages decoded ahead would only push out pages in use), nor under
  // --lod-under-pressure; the pass evicts nothing (FramePlan::decodeAhead) and holds one band of
  // next.bandRows rows of pixels at a time. `next`'s volume and transfer function must
  // outlive the pass.
  void decodeAhead(const RankFrame& next, int reduce = 2);
  // Ends decoding ahead, if any: returns once its blocks in flight have finished.
  void endAhead();
  // Waits until decoding ahead, if any, has gone over all it was to decode (a rank with nothing
  // else to do; the tests).
  void finishAhead();

  // Predicts what the whole screen of `frame` (its rectangles are ignored) costs at full
  // resolution on this rank alone: the screen at 1/step a side, a ray a pixel, scaled by step^2.
  // A probe of the view before a frame has been measured (a steered job's first frame).
  FrameProbe probe(const RankFrame& frame, int step = 16);

  // This process's memory now, without rendering anything.
  ProcessMemory memory() const { return processMemory(); }

 private:
  const FramePlan& plan(const RankFrame& frame);
  TileStats renderPart(const RankFrame& frame, const Rect& part, Image& image, CostGrid& costs);
  void releaseWhenSettled(const PageStats& frame);

  Backend& backend_;
  const RenderSettings& settings_;
  std::optional<FramePlan> plan_;
  // What the kept plan's transfer-function part was made for.
  const RenderVolume* planVolume_ = nullptr;
  int planStep_ = -1;
  const TransferFunction* planTf_ = nullptr;
  // Pages were decoded since the decode sources were last released (releaseWhenSettled).
  bool decodedSinceRelease_ = false;
  std::atomic<bool> stop_{false};
  // The last frame's pages: whether its rays read decoded pages, and evicted any.
  bool lastPaged_ = false, lastEvicted_ = false;
  // Decoding ahead: the pass in flight (its pages decoded), told to stop by aheadStop_, and the
  // pages the passes ended since the last frame decoded.
  std::future<std::uint64_t> ahead_;
  std::atomic<bool> aheadStop_{false};
  std::uint64_t aheadDecoded_ = 0;
  // The last pass's plan (its transfer-function part serves the next frame's plan when that
  // frame shows the same volume, step and transfer function), made on the pass's thread.
  std::optional<FramePlan> aheadPlan_;
  const RenderVolume* aheadVolume_ = nullptr;
  int aheadStep_ = -1;
  const TransferFunction* aheadTf_ = nullptr;
};

}  // namespace voxwall::node
