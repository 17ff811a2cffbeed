#include <algorithm>
#include <cmath>
#include <cstring>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/master/frame_messages.hpp>

namespace voxwall::master {
namespace {

using voxwall::ByteReader;
using voxwall::ByteWriter;

void putRect(ByteWriter& w, const voxwall::Rect& r) {
  w.put<std::int32_t>(r.x), w.put<std::int32_t>(r.y);
  w.put<std::int32_t>(r.width), w.put<std::int32_t>(r.height);
}

voxwall::Rect getRect(ByteReader& r, int screenWidth, int screenHeight) {
  voxwall::Rect rect;
  rect.x = r.get<std::int32_t>(), rect.y = r.get<std::int32_t>();
  rect.width = r.get<std::int32_t>(), rect.height = r.get<std::int32_t>();
  if (!rect.fitsIn(screenWidth, screenHeight))
    r.fail("rectangle " + std::to_string(rect.width) + "x" + std::to_string(rect.height) + "+" +
           std::to_string(rect.x) + "+" + std::to_string(rect.y) + " is not on the " +
           std::to_string(screenWidth) + "x" + std::to_string(screenHeight) + " screen");
  return rect;
}

void expectHeader(ByteReader& r, std::uint32_t magic, const char* name) {
  if (r.get<std::uint32_t>() != magic) r.fail(std::string("not a ") + name + " message");
  const auto version = r.get<std::uint32_t>();
  if (version != kFrameMessageVersion)
    r.fail(std::string(name) + " version " + std::to_string(version) + ", this program speaks " +
           std::to_string(kFrameMessageVersion) + " (mixed voxwall versions in one job?)");
}

void putCamera(ByteWriter& w, const node::Camera& camera) {
  for (const glm::dvec3& v : {camera.eye, camera.center, camera.up})
    w.put(v.x), w.put(v.y), w.put(v.z);
  w.put(camera.fovYDeg);
}

node::Camera getCamera(ByteReader& r) {
  node::Camera camera;
  for (glm::dvec3* v : {&camera.eye, &camera.center, &camera.up})
    v->x = r.get<double>(), v->y = r.get<double>(), v->z = r.get<double>();
  camera.fovYDeg = r.get<double>();
  for (double v : {camera.eye.x, camera.eye.y, camera.eye.z, camera.center.x, camera.center.y,
                   camera.center.z, camera.up.x, camera.up.y, camera.up.z})
    if (!std::isfinite(v)) r.fail("camera is not finite");
  if (!(camera.fovYDeg > 0 && camera.fovYDeg < 180)) r.fail("camera field of view");
  return camera;
}

}  // namespace

std::vector<std::byte> encode(const FrameTask& t) {
  std::vector<std::byte> out;
  ByteWriter w(out);
  w.put(kFrameTaskMagic), w.put(kFrameMessageVersion);
  const std::uint32_t phase = t.phase == net::FramePhase::Interactive ? 2u
                              : t.phase == net::FramePhase::Refining  ? 4u
                                                                      : 0u;
  w.put<std::uint32_t>(t.frame),
      w.put<std::uint32_t>((t.stop ? 1u : 0u) | phase | (t.ahead ? 8u : 0u));
  w.put<std::uint64_t>(t.decidedUnixMicros);
  w.put<std::uint64_t>(t.jobId);
  putCamera(w, t.camera);
  w.put<std::uint32_t>(t.watchdogMs);
  w.put<std::int32_t>(t.screenWidth), w.put<std::int32_t>(t.screenHeight);
  w.put<std::int32_t>(t.cellPixels);
  w.put<std::int32_t>(t.step);
  w.put<std::uint32_t>(t.timeStep);
  if (t.ahead) putCamera(w, t.aheadCamera), w.put<std::uint32_t>(t.aheadTimeStep);
  w.put<std::uint32_t>(std::uint32_t(t.rects.size()));
  for (const auto& rects : t.rects) {
    w.put<std::uint32_t>(std::uint32_t(rects.size()));
    for (const auto& r : rects) putRect(w, r);
  }
  return out;
}

FrameTask decodeFrameTask(std::span<const std::byte> bytes, const std::string& source) {
  ByteReader r(bytes, source, "frame task");
  expectHeader(r, kFrameTaskMagic, "frame task");
  FrameTask t;
  t.frame = r.get<std::uint32_t>();
  const auto flags = r.get<std::uint32_t>();
  if ((flags & ~15u) != 0 || (flags & 6) == 6) r.fail("unknown flags " + std::to_string(flags));
  t.stop = flags & 1;
  t.ahead = flags & 8;
  t.phase = flags & 2   ? net::FramePhase::Interactive
            : flags & 4 ? net::FramePhase::Refining
                        : net::FramePhase::Full;
  t.decidedUnixMicros = r.get<std::uint64_t>();
  t.jobId = r.get<std::uint64_t>();
  t.camera = getCamera(r);
  t.watchdogMs = r.get<std::uint32_t>();
  t.screenWidth = r.get<std::int32_t>(), t.screenHeight = r.get<std::int32_t>();
  t.cellPixels = r.get<std::int32_t>();
  if (t.screenWidth <= 0 || t.screenHeight <= 0 || t.screenWidth > kMaxScreenSide ||
      t.screenHeight > kMaxScreenSide)
    r.fail("screen size " + std::to_string(t.screenWidth) + "x" + std::to_string(t.screenHeight));
  if (t.cellPixels <= 0 || t.cellPixels > kMaxScreenSide) r.fail("cost cell size");
  t.step = r.get<std::int32_t>();
  if (t.step < 1 || t.step > kMaxTaskStep) r.fail("step " + std::to_string(t.step));
  t.timeStep = r.get<std::uint32_t>();
  if (t.timeStep >= kMaxTimeSteps) r.fail("time step " + std::to_string(t.timeStep));
  if (t.ahead) {
    t.aheadCamera = getCamera(r);
    t.aheadTimeStep = r.get<std::uint32_t>();
    if (t.aheadTimeStep >= kMaxTimeSteps)
      r.fail("next frame's time step " + std::to_string(t.aheadTimeStep));
  }
  const auto ranks = r.get<std::uint32_t>();
  if (ranks > std::uint32_t(kMaxRanks)) r.fail(std::to_string(ranks) + " ranks");
  // Each rank takes at least 4 bytes: a count larger than the rest of the message is corrupt.
  if (ranks > r.remaining() / 4) r.fail("rank count larger than the message");
  t.rects.resize(ranks);
  for (auto& rects : t.rects) {
    const auto n = r.get<std::uint32_t>();
    if (n > std::uint32_t(kMaxRectsPerRank) || n > r.remaining() / 16)
      r.fail(std::to_string(n) + " rectangles for one rank");
    rects.reserve(n);
    for (std::uint32_t i = 0; i < n; ++i)
      rects.push_back(getRect(r, t.screenWidth, t.screenHeight));
  }
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " trailing bytes");
  return t;
}

std::vector<std::byte> encode(const RankReport& rep) {
  std::vector<std::byte> out;
  std::size_t pixels = 0;
  for (const auto& t : rep.tiles) pixels += t.image.pixels.size();
  out.reserve(64 + rep.tiles.size() * 16 + pixels * 4 + rep.costs.seconds.size() * 8);
  ByteWriter w(out);
  w.put(kRankReportMagic), w.put(kFrameMessageVersion);
  w.put<std::uint32_t>(rep.frame), w.put<std::int32_t>(rep.rank);
  w.put(rep.renderSeconds), w.put<std::uint64_t>(rep.samples);
  w.put<std::uint64_t>(rep.residentBytes), w.put<std::uint64_t>(rep.peakResidentBytes);
  w.put<std::uint64_t>(rep.privateBytes), w.put<std::uint64_t>(rep.fileBytes);
  w.put<std::uint64_t>(rep.sharedBytes);
  w.put<std::uint64_t>(rep.pages.hits), w.put<std::uint64_t>(rep.pages.missed);
  w.put<std::uint64_t>(rep.pages.decoded);
  w.put<std::uint64_t>(rep.pages.evictions), w.put<std::uint64_t>(rep.pages.residentBytes);
  w.put<std::uint64_t>(rep.pages.coarse), w.put<std::uint64_t>(rep.pages.waited);
  w.put<std::uint64_t>(rep.pages.ahead);
  w.put<std::uint64_t>(rep.rays), w.put<std::int32_t>(rep.latticeStride);
  w.put<std::uint32_t>((rep.pixels ? 1u : 0u) | (rep.streamed ? 2u : 0u) |
                       (rep.streamRefused ? 4u : 0u) | (rep.abandoned ? 8u : 0u));
  w.put(rep.encodeSeconds), w.put<std::uint64_t>(rep.streamedBytes);
  const std::string error = rep.streamError.substr(0, kMaxStreamError);
  w.put<std::uint16_t>(std::uint16_t(error.size()));
  w.putBytes(std::as_bytes(std::span(error)));
  w.put<std::uint32_t>(std::uint32_t(rep.tiles.size()));
  for (const auto& t : rep.tiles) {
    putRect(w, t.rect);
    if (rep.pixels) {
      if (t.image.width != t.rect.width || t.image.height != t.rect.height)
        throw std::invalid_argument("rank report: a tile's pixels do not match its rectangle");
      w.putBytes(std::as_bytes(std::span(t.image.pixels)));
    }
  }
  // Only the cells under this rank's tiles travel: the wire cost of the grid is O(cells) for the
  // whole job, not O(cells x ranks).
  int cx0 = 0, cy0 = 0, cx1 = 0, cy1 = 0;  // [cx0, cx1) x [cy0, cy1)
  const auto& g = rep.costs;
  if (g.cellsX > 0 && !rep.tiles.empty()) {
    cx0 = g.cellsX, cy0 = g.cellsY;
    for (const auto& t : rep.tiles) {
      cx0 = std::min(cx0, t.rect.x / g.cellPixels);
      cy0 = std::min(cy0, t.rect.y / g.cellPixels);
      cx1 = std::max(cx1, (t.rect.x + t.rect.width - 1) / g.cellPixels + 1);
      cy1 = std::max(cy1, (t.rect.y + t.rect.height - 1) / g.cellPixels + 1);
    }
    cx1 = std::min(cx1, g.cellsX), cy1 = std::min(cy1, g.cellsY);
  }
  w.put<std::int32_t>(g.cellsX > 0 ? g.cellsX : 0),
      w.put<std::int32_t>(g.cellsX > 0 ? g.cellsY : 0);
  w.put<std::int32_t>(cx0), w.put<std::int32_t>(cy0);
  w.put<std::int32_t>(std::max(0, cx1 - cx0)), w.put<std::int32_t>(std::max(0, cy1 - cy0));
  for (int cy = cy0; cy < cy1; ++cy)
    for (int cx = cx0; cx < cx1; ++cx) w.put(g.at(cx, cy));
  return out;
}

RankReport decodeRankReport(std::span<const std::byte> bytes, const FrameTask& task,
                            const std::string& source) {
  ByteReader r(bytes, source, "rank report");
  expectHeader(r, kRankReportMagic, "rank report");
  RankReport rep;
  rep.frame = r.get<std::uint32_t>();
  if (rep.frame != task.frame)
    r.fail("answers frame " + std::to_string(rep.frame) + " instead of " +
           std::to_string(task.frame));
  rep.rank = r.get<std::int32_t>();
  rep.renderSeconds = r.get<double>();
  rep.samples = r.get<std::uint64_t>();
  rep.residentBytes = r.get<std::uint64_t>(), rep.peakResidentBytes = r.get<std::uint64_t>();
  rep.privateBytes = r.get<std::uint64_t>(), rep.fileBytes = r.get<std::uint64_t>();
  rep.sharedBytes = r.get<std::uint64_t>();
  rep.pages.hits = r.get<std::uint64_t>(), rep.pages.missed = r.get<std::uint64_t>();
  rep.pages.decoded = r.get<std::uint64_t>();
  rep.pages.evictions = r.get<std::uint64_t>(), rep.pages.residentBytes = r.get<std::uint64_t>();
  rep.pages.coarse = r.get<std::uint64_t>(), rep.pages.waited = r.get<std::uint64_t>();
  rep.pages.ahead = r.get<std::uint64_t>();
  rep.rays = r.get<std::uint64_t>();
  rep.latticeStride = r.get<std::int32_t>();
  if (rep.latticeStride < 0 || rep.latticeStride > kMaxScreenSide)
    r.fail("has a ray lattice of stride " + std::to_string(rep.latticeStride));
  const auto flags = r.get<std::uint32_t>();
  if (flags > 15) r.fail("unknown flags " + std::to_string(flags));
  rep.pixels = flags & 1, rep.streamed = flags & 2, rep.streamRefused = flags & 4;
  rep.abandoned = flags & 8;
  rep.encodeSeconds = r.get<double>();
  rep.streamedBytes = r.get<std::uint64_t>();
  const auto errorBytes = r.get<std::uint16_t>();
  if (errorBytes > kMaxStreamError)
    r.fail("stream error of " + std::to_string(errorBytes) + " bytes");
  const auto error = r.getBytes(errorBytes);
  rep.streamError.assign(reinterpret_cast<const char*>(error.data()), error.size());
  const auto tiles = r.get<std::uint32_t>();
  if (tiles > std::uint32_t(kMaxRectsPerRank) || tiles > r.remaining() / 16)
    r.fail(std::to_string(tiles) + " tiles");
  rep.tiles.resize(tiles);
  for (auto& t : rep.tiles) {
    t.rect = getRect(r, task.screenWidth, task.screenHeight);
    if (!rep.pixels) continue;
    const std::size_t n = std::size_t(t.rect.width) * std::size_t(t.rect.height);
    if (n > r.remaining() / 4) r.fail("tile pixels truncated");
    t.image = voxwall::Image(t.rect.width, t.rect.height);
    const auto src = r.getBytes(n * 4);
    std::memcpy(t.image.pixels.data(), src.data(), n * 4);
  }
  const int cellsX = r.get<std::int32_t>(), cellsY = r.get<std::int32_t>();
  const int cx0 = r.get<std::int32_t>(), cy0 = r.get<std::int32_t>();
  const int cw = r.get<std::int32_t>(), ch = r.get<std::int32_t>();
  if (cellsX != 0 || cellsY != 0) {
    node::CostGrid grid(task.screenWidth, task.screenHeight, task.cellPixels);
    if (cellsX != grid.cellsX || cellsY != grid.cellsY)
      r.fail("cost grid " + std::to_string(cellsX) + "x" + std::to_string(cellsY) +
             " does not match the screen's " + std::to_string(grid.cellsX) + "x" +
             std::to_string(grid.cellsY));
    if (cx0 < 0 || cy0 < 0 || cw < 0 || ch < 0 || cw > grid.cellsX - cx0 || ch > grid.cellsY - cy0)
      r.fail("cost cells outside the grid");
    if (std::size_t(cw) * std::size_t(ch) > r.remaining() / 8) r.fail("cost cells truncated");
    for (int cy = cy0; cy < cy0 + ch; ++cy)
      for (int cx = cx0; cx < cx0 + cw; ++cx) grid.at(cx, cy) = r.get<double>();
    rep.costs = std::move(grid);
  } else if (cx0 != 0 || cy0 != 0 || cw != 0 || ch != 0) {
    r.fail("cost cells without a grid");
  }
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " trailing bytes");
  return rep;
}

}  // namespace voxwall::master
