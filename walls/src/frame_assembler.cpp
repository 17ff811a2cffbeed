#include <algorithm>
#include <bit>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/walls/frame_assembler.hpp>

namespace voxwall::walls {

namespace {
constexpr std::size_t kReportedKept = 4096;  // frames whose fate is remembered
}

std::uint64_t defaultPendingBytes(const Wall& wall) {
  return 2 * std::uint64_t(wall.width) * std::uint64_t(wall.height) * 4 + (64ull << 20);
}

FrameAssembler::FrameAssembler(const Wall& wall, AssemblerLimits limits, Events events)
    : wall_(wall), limits_(limits), events_(std::move(events)) {
  if (limits_.pendingFrames < 1) limits_.pendingFrames = 1;
  if (limits_.pendingBytes == 0) limits_.pendingBytes = defaultPendingBytes(wall);
  if (limits_.frameWindow == 0) limits_.frameWindow = 1;
  const std::size_t pixels = std::size_t(wall.width) * std::size_t(wall.height);
  coverageBytes_ = (pixels + 63) / 64 * 8;
  const std::uint64_t frameBytes = std::uint64_t(pixels) * 4 + coverageBytes_;
  if (limits_.pendingBytes < frameBytes)
    throw std::invalid_argument("memory for open frames (--pending-mib) is " +
                                std::to_string(limits_.pendingBytes >> 20) +
                                " MiB, less than one frame of this wall (" +
                                std::to_string((frameBytes + (1 << 20) - 1) >> 20) + " MiB)");
  displayMask_.assign(pixels, 0);
  for (const auto& d : wall.displays)
    for (int y = d.rect.y; y < d.rect.y + d.rect.height; ++y)
      std::fill_n(displayMask_.begin() + std::ptrdiff_t(std::size_t(y) * std::size_t(wall.width) +
                                                        std::size_t(d.rect.x)),
                  d.rect.width, std::uint8_t(1));
  displayPixels_ = wall.displayPixels();
}

void FrameAssembler::report(std::uint64_t frame, net::FrameStatus status, const std::string& why) {
  if (!reported_.insert(frame).second) return;
  if (reported_.size() > kReportedKept) reported_.erase(reported_.begin());
  if (status != net::FrameStatus::Presented && events_) events_({frame, {status, why}});
}

void FrameAssembler::drop(std::uint64_t frame, const std::string& why) {
  const auto it = open_.find(frame);
  if (it == open_.end()) return;
  const long long covered = it->second.coveredDisplayPixels;
  heldBytes_ -= it->second.heldBytes;
  open_.erase(it);
  char share[64];
  std::snprintf(share, sizeof share, " (%.1f%% of display pixels arrived)",
                100.0 * double(covered) / double(std::max<long long>(1, displayPixels_)));
  report(frame, net::FrameStatus::Dropped, why + share);
}

void FrameAssembler::startSequence(std::uint64_t firstFrame, const std::string& why) {
  while (!open_.empty()) drop(open_.begin()->first, why);
  firstFrame_ = firstFrame;
  lastComplete_.reset();
  reported_.clear();
}

std::optional<std::string> FrameAssembler::outsideWindow(std::uint64_t frame) const {
  const std::uint64_t w = limits_.frameWindow;
  if (lastComplete_) {
    if (frame <= *lastComplete_)
      return "older than frame " + std::to_string(*lastComplete_) + ", which was complete";
    if (frame - *lastComplete_ > w)
      return "more than " + std::to_string(w) + " frames ahead of frame " +
             std::to_string(*lastComplete_) + ", the last complete one";
    return std::nullopt;
  }
  if (frame < firstFrame_)
    return "before frame " + std::to_string(firstFrame_) + ", where the job starts";
  if (frame - firstFrame_ > w)
    return "more than " + std::to_string(w) + " frames ahead of frame " +
           std::to_string(firstFrame_) + ", where the job starts";
  return std::nullopt;
}

std::optional<AssembledFrame> FrameAssembler::addTile(std::uint64_t frame,
                                                      const net::TileMessage& tile, int rank,
                                                      const std::string& peer) {
  const auto& sent = tile.rect;
  const int step = tile.step;
  if (step < 1 || step > net::kMaxStep)
    throw FormatError(peer, "tile step " + std::to_string(step) + " is not in [1, " +
                                std::to_string(net::kMaxStep) + "]");
  const int screenW = net::reducedSide(wall_.width, step);
  const int screenH = net::reducedSide(wall_.height, step);
  // The one check of a rectangle from the wire against the screen (64-bit: no overflow).
  if (!sent.fitsIn(screenW, screenH))
    throw FormatError(peer, "tile " + std::to_string(sent.width) + "x" +
                                std::to_string(sent.height) + "+" + std::to_string(sent.x) + "+" +
                                std::to_string(sent.y) + " is not on the " +
                                std::to_string(screenW) + "x" + std::to_string(screenH) +
                                (step > 1 ? " reduced screen (step " + std::to_string(step) + ")"
                                          : std::string(" screen")));
  const voxwall::Rect r = net::fullScreenRect(sent, step, wall_.width, wall_.height);
  auto it = open_.find(frame);
  if (it != open_.end() && it->second.info.step != step)
    throw FormatError(peer, "tile of frame " + std::to_string(frame) + " at step " +
                                std::to_string(step) + ", its other tiles are at step " +
                                std::to_string(it->second.info.step));
  if (it == open_.end()) {
    if (reported(frame)) return std::nullopt;  // settled; its fate was reported
    if (const auto why = outsideWindow(frame)) {
      report(frame, net::FrameStatus::Refused, "frame id " + std::to_string(frame) + " is " + *why);
      return std::nullopt;
    }
  }
  // Make room before decoding: what a tile costs is known from its rectangle.
  const std::uint64_t need =
      std::uint64_t(sent.area()) * 4 + (it == open_.end() ? coverageBytes_ : 0);
  while (heldBytes_ + need > limits_.pendingBytes) {
    auto victim = open_.begin();
    if (victim != open_.end() && victim->first == frame) ++victim;
    if (victim == open_.end()) {  // this frame alone holds too much (overlapping tiles)
      drop(frame, "over the sink's memory limit for open frames");
      return std::nullopt;
    }
    drop(victim->first, "over the sink's memory limit for open frames");
  }
  if (it == open_.end())
    while (int(open_.size()) >= limits_.pendingFrames)
      drop(open_.begin()->first, "too many frames open");
  // Decode before touching the frame: a corrupt tile must not mark any pixel as arrived.
  voxwall::Image image = net::decodeTile(tile.bytes, tile.codec, sent.width, sent.height, peer);
  it = open_.find(frame);
  if (it == open_.end()) {
    it = open_.emplace(frame, Open{}).first;
    it->second.covered.assign(coverageBytes_ / 8, 0);
    it->second.heldBytes = coverageBytes_;
    it->second.info.frame = frame;
    it->second.info.step = step;
    heldBytes_ += coverageBytes_;
  }
  Open& f = it->second;
  for (int y = 0; y < r.height; ++y) {
    const std::size_t row = std::size_t(r.y + y) * std::size_t(wall_.width) + std::size_t(r.x);
    for (std::size_t i = row; i < row + std::size_t(r.width); ++i) {
      std::uint64_t& word = f.covered[i / 64];
      const std::uint64_t bit = 1ull << (i % 64);
      if (word & bit) continue;
      word |= bit;
      f.coveredDisplayPixels += displayMask_[i];
    }
  }
  const std::uint64_t tileBytes = std::uint64_t(sent.area()) * 4;
  f.heldBytes += tileBytes;
  heldBytes_ += tileBytes;
  f.tiles.emplace_back(r, std::move(image));
  auto& info = f.info;
  info.placements.push_back({r, rank});
  info.rankRenderMicros[rank] = tile.renderMicros;
  info.decidedUnixMicros = info.decidedUnixMicros
                               ? std::min(info.decidedUnixMicros, tile.decidedUnixMicros)
                               : tile.decidedUnixMicros;
  info.bytes += tile.bytes.size();
  ++info.tiles;
  if (f.coveredDisplayPixels < displayPixels_) return std::nullopt;

  // Complete: older frames can never be shown now, and frames far ahead are bogus.
  while (open_.begin()->first != frame) drop(open_.begin()->first, "a newer frame completed");
  AssembledFrame done = std::move(f.info);
  done.image = voxwall::Image(wall_.width, wall_.height);
  for (const auto& [rect, pixels] : f.tiles) {
    if (done.step == 1) {
      done.image.paste(pixels, rect);
      continue;
    }
    // Upsample: every pixel of the block repeats its reduced pixel (the rectangle starts on a
    // block boundary; blocks at the screen's right and bottom edges are clipped).
    const int s = done.step, x0 = rect.x / s, y0 = rect.y / s;
    for (int y = 0; y < rect.height; ++y) {
      const int sy = (rect.y + y) / s - y0;
      for (int x = 0; x < rect.width; ++x)
        done.image.at(rect.x + x, rect.y + y) = pixels.at((rect.x + x) / s - x0, sy);
    }
  }
  heldBytes_ -= f.heldBytes;
  open_.erase(open_.begin());
  lastComplete_ = frame;
  report(frame, net::FrameStatus::Presented, "");
  while (!open_.empty() && open_.rbegin()->first - frame > limits_.frameWindow)
    drop(open_.rbegin()->first, "outside the frame window after frame " + std::to_string(frame));
  return done;
}

}  // namespace voxwall::walls
