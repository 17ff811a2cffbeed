#include <chrono>
#include <future>
#include <stdexcept>
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

RankRenderer::RankRenderer(Backend& backend, const RenderSettings& settings)
    : backend_(backend), settings_(settings) {}

// The transfer function's part of a plan (its LUT and skip grids: most of the planning time on a
// large volume) is kept while the volume, its time step and the transfer function stay; a frame
// of another step plans afresh, since its value ranges skip other cells.
const FramePlan& RankRenderer::plan(const RankFrame& frame) {
  const bool same = plan_ && planVolume_ == frame.volume && planStep_ == frame.volume->step() &&
                    planTf_ == frame.tf;
  plan_ = planFrame(*frame.volume, frame.camera, frame.screenWidth, frame.screenHeight, *frame.tf,
                    settings_, same ? &*plan_ : nullptr);
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
  RankFrameResult result;
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
  releaseWhenSettled(result.pages);
  return result;
}

FrameProbe RankRenderer::probe(const RankFrame& frame, int step) {
  if (step < 1) throw std::invalid_argument("probe step must be at least 1");
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
  } else if (frame.decoded > 0) {
    decodedSinceRelease_ = true;
  } else if (decodedSinceRelease_ && planVolume_) {
    planVolume_->releaseDecodeSources();
    returnFreeMemory();  // the tables were freed in pieces the allocator would keep
    decodedSinceRelease_ = false;
  }
}

}  // namespace voxwall::node
