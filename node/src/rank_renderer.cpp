#include <algorithm>
#include <chrono>
#include <future>
#include <stdexcept>
#include <utility>
#include <voxwall/core/parallel.hpp>
#include <voxwall/node/rank_renderer.hpp>

namespace voxwall::node {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

void add(PageStats& sum, const TileStats& stats) {
  sum.hits += stats.pageHits, sum.missed += stats.pageMissed;
  sum.decoded += stats.pageDecoded;
  sum.evictions += stats.pageEvictions;
  sum.coarse += stats.pageCoarse;
  sum.waited += stats.pageWaited;
  sum.residentBytes = stats.pageResidentBytes;
}

}  // namespace

std::vector<Rect> rowBands(const Rect& rect, int rows) {
  rows = std::max(1, rows);
  std::vector<Rect> out;
  for (int y = 0; y < rect.height; y += rows)
    out.push_back({rect.x, rect.y + y, rect.width, std::min(rows, rect.height - y)});
  return out;
}

std::vector<Rect> reducedRects(const std::vector<Rect>& rects, int width, int height, int step) {
  step = std::max(1, step);
  const auto edge = [step](int e, int side) {
    return e >= side ? (side + step - 1) / step : e / step;
  };
  std::vector<Rect> out;
  for (const Rect& r : rects) {
    const int x0 = edge(r.x, width), x1 = edge(r.x + r.width, width);
    const int y0 = edge(r.y, height), y1 = edge(r.y + r.height, height);
    if (x1 > x0 && y1 > y0) out.push_back({x0, y0, x1 - x0, y1 - y0});
  }
  return out;
}

RankRenderer::RankRenderer(Backend& backend, const RenderSettings& settings)
    : backend_(backend), settings_(settings) {}

RankRenderer::~RankRenderer() {
  try {
    endAhead();
  } catch (const std::exception&) {
    // A pass that failed leaves nothing to undo; the job is ending anyway.
  }
}

// The transfer function's part of a plan (its LUT and skip grids: most of the planning time on a
// large volume) is kept while the volume, its time step and the transfer function stay; a frame
// of another step plans afresh, since its value ranges skip other cells.
const FramePlan& RankRenderer::plan(const RankFrame& frame) {
  const bool same = plan_ && planVolume_ == frame.volume && planStep_ == frame.volume->step() &&
                    planTf_ == frame.tf;
  const bool ahead = aheadPlan_ && aheadVolume_ == frame.volume &&
                     aheadStep_ == frame.volume->step() && aheadTf_ == frame.tf;
  plan_ = planFrame(*frame.volume, frame.camera, frame.screenWidth, frame.screenHeight, *frame.tf,
                    settings_,
                    same    ? &*plan_
                    : ahead ? &*aheadPlan_
                            : nullptr);
  planVolume_ = frame.volume, planStep_ = frame.volume->step(), planTf_ = frame.tf;
  return *plan_;
}

// Renders `part` on the backend's threads while this thread polls frame.abandoned; once it says
// the frame is given up, the backend leaves the part unfinished.
TileStats RankRenderer::renderPart(const RankFrame& frame, const Rect& part, Image& image,
                                   CostGrid& costs) {
  const FramePlan& plan = *plan_;
  if (!frame.abandoned) return backend_.render(*frame.volume, plan, part, image, &costs);
  if (stop_ || frame.abandoned()) {
    stop_ = true;
    TileStats stopped;
    stopped.stopped = true;
    return stopped;
  }
  auto done = std::async(std::launch::async, [&] {
    return backend_.render(*frame.volume, plan, part, image, &costs, &stop_);
  });
  while (done.wait_for(std::chrono::milliseconds(2)) != std::future_status::ready)
    if (!stop_ && frame.abandoned()) stop_ = true;
  return done.get();
}

RankFrameResult RankRenderer::render(const RankFrame& frame) {
  endAhead();
  RankFrameResult result;
  result.pages.ahead = std::exchange(aheadDecoded_, 0);
  if (frame.rects.empty()) return result;
  result.latticeStride = plan(frame).latticeStride;
  result.costs = CostGrid(frame.screenWidth, frame.screenHeight, frame.cellPixels);
  stop_ = false;
  bool handing = bool(frame.onPart);
  for (const Rect& rect : frame.rects) {
    const auto parts = frame.keepPixels ? std::vector<Rect>{rect} : rowBands(rect, frame.bandRows);
    Image image;  // with pixels, the whole rectangle (one part)
    for (const Rect& part : parts) {
      // Abandoned while parts are left: they are not rendered. (Once every part is done, the
      // word comes too late: the tiles are whole, and the frame is not abandoned here.)
      if (stop_) {
        result.abandoned = true;
        break;
      }
      image = Image();  // the last band goes before the backend makes the next
      const auto start = Clock::now();
      const TileStats stats = renderPart(frame, part, image, result.costs);
      result.samples += stats.samples;
      result.rays += stats.rays;
      add(result.pages, stats);
      result.renderSeconds += since(start);
      if (stats.stopped) {
        result.abandoned = true;
        break;
      }
      if (handing) handing = frame.onPart(part, image, result.renderSeconds);
    }
    result.tiles.push_back({rect, frame.keepPixels ? std::move(image) : Image()});
  }
  lastPaged_ = result.pages.hits + result.pages.missed > 0;
  lastEvicted_ = result.pages.evictions > 0;
  releaseWhenSettled(result.pages);
  return result;
}

void RankRenderer::decodeAhead(const RankFrame& next, int reduce) {
  endAhead();
  // (Under --lod-under-pressure a lane that finds no free slot marks its page wanted, and a page
  // the pass marked would be sampled coarser in the next frame than without the pass.)
  if (settings_.lodUnderPressure || !lastPaged_ || lastEvicted_ || !next.volume || !next.tf) return;
  reduce = std::max(1, reduce);
  const int width = (next.screenWidth + reduce - 1) / reduce;
  const int height = (next.screenHeight + reduce - 1) / reduce;
  std::vector<Rect> rects = reducedRects(next.rects, next.screenWidth, next.screenHeight, reduce);
  if (rects.empty()) return;
  const FramePlan* reuse =
      plan_ && planVolume_ == next.volume && planStep_ == next.volume->step() && planTf_ == next.tf
          ? &*plan_
          : nullptr;
  aheadPlan_.reset();
  aheadVolume_ = next.volume, aheadStep_ = next.volume->step(), aheadTf_ = next.tf;
  aheadStop_ = false;
  ahead_ =
      std::async(std::launch::async, [this, next, width, height, reuse, rects = std::move(rects)] {
        // Its threads take only what the host's other work leaves: on a host shared by ranks, a
        // rank that finished first must not slow the others' frames with the next one's pages.
        yieldCoresToOthers();
        aheadPlan_ =
            planFrame(*next.volume, next.camera, width, height, *next.tf, settings_, reuse);
        aheadPlan_->decodeAhead = true;
        std::uint64_t decoded = 0;
        for (const Rect& r : rects)
          for (const Rect& band : rowBands(r, next.bandRows)) {  // one band's pixels at a time
            if (aheadStop_) break;
            Image pixels;
            const TileStats stats =
                backend_.render(*next.volume, *aheadPlan_, band, pixels, nullptr, &aheadStop_);
            decoded += stats.pageDecoded - stats.pageScratch;  // the pages kept for the frame
          }
        return decoded;
      });
}

void RankRenderer::endAhead() {
  aheadStop_ = true;
  finishAhead();
}

void RankRenderer::finishAhead() {
  if (ahead_.valid()) aheadDecoded_ += ahead_.get();
}

FrameProbe RankRenderer::probe(const RankFrame& frame, int step) {
  if (step < 1) throw std::invalid_argument("probe step must be at least 1");
  endAhead();
  RankFrame reduced = frame;
  reduced.screenWidth = (frame.screenWidth + step - 1) / step;
  reduced.screenHeight = (frame.screenHeight + step - 1) / step;
  reduced.rects = {{0, 0, reduced.screenWidth, reduced.screenHeight}};
  reduced.keepPixels = true;
  reduced.abandoned = nullptr;
  reduced.onPart = nullptr;
  const RankFrameResult result = render(reduced);
  const double scale = double(step) * double(step);
  return {result.renderSeconds * scale, std::uint64_t(double(result.samples) * scale)};
}

// Decoded pages hold the voxels their compressed bytes gave: those bytes (and the tables the codec
// made to decode them) are read again only to decode a page anew, so once the view has settled
// (the first frame that decodes nothing after frames that did) they need not stay resident: a
// rank's memory is then its pages, not its pages and their source too. A later frame that decodes
// takes them back (the file from the system's page cache). Not while every frame decodes (a
// moving camera: remaking tvq's codebooks each frame cost 15-30% of an orbit's frame time), nor
// when pages were evicted (the working set is over the budget), nor for rays that sample the file
// directly (raw volumes, per-ray decoding), which decode no pages.
void RankRenderer::releaseWhenSettled(const PageStats& frame) {
  if (frame.evictions > 0) {
    decodedSinceRelease_ = false;
  } else if (frame.decoded + frame.ahead > 0) {
    decodedSinceRelease_ = true;
  } else if (decodedSinceRelease_ && planVolume_) {
    planVolume_->releaseDecodeSources();
    returnFreeMemory();  // the tables were freed in pieces the allocator would keep
    decodedSinceRelease_ = false;
  }
}

}  // namespace voxwall::node
