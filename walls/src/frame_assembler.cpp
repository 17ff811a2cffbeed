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
  // One frame of raw RGBA pixels must fit, whatever the tiles' codec.
  const std::uint64_t frameBytes = std::uint64_t(pixels) * 4 + coverageBytes_;
  if (limits_.pendingBytes < frameBytes)
    throw std::invalid_argument("memory for open frames (--pending-mib) is " +
                                std::to_string(limits_.pendingBytes >> 20) +
                                " MiB, less than one frame of this wall (" +
                                std::to_string((frameBytes + (1 << 20) - 1) >> 20) + " MiB)");
  needed_.assign(coverageBytes_ / 8, 0);
  if (limits_.wholeScreen) {
    for (std::size_t i = 0; i < pixels; ++i) needed_[i / 64] |= 1ull << (i % 64);
    neededPixels_ = (long long)pixels;
  } else {
    for (const auto& d : wall.displays)
      for (int y = d.rect.y; y < d.rect.y + d.rect.height; ++y) {
        const std::size_t row = std::size_t(y) * std::size_t(wall.width) + std::size_t(d.rect.x);
        for (std::size_t i = row; i < row + std::size_t(d.rect.width); ++i)
          needed_[i / 64] |= 1ull << (i % 64);
      }
    neededPixels_ = wall.displayPixels();
  }
}

void FrameAssembler::cover(Open& f, const voxwall::Rect& r) const {
  // Word by word: a bigeye frame is 25 Mpx, a bit at a time would cost tens of milliseconds.
  for (int y = 0; y < r.height; ++y) {
    const std::size_t begin = std::size_t(r.y + y) * std::size_t(wall_.width) + std::size_t(r.x);
    const std::size_t end = begin + std::size_t(r.width);
    for (std::size_t w = begin / 64; w <= (end - 1) / 64; ++w) {
      std::uint64_t bits = ~0ull;
      if (w == begin / 64) bits &= ~0ull << (begin % 64);
      if (w == (end - 1) / 64 && end % 64) bits &= ~0ull >> (64 - end % 64);
      const std::uint64_t fresh = bits & ~f.covered[w];
      f.covered[w] |= bits;
      f.coveredPixels += std::popcount(fresh & needed_[w]);
    }
  }
}

void FrameAssembler::report(std::uint64_t frame, net::FrameStatus status, const std::string& why) {
  if (!reported_.insert(frame).second) return;
  if (reported_.size() > kReportedKept) reported_.erase(reported_.begin());
  if (status != net::FrameStatus::Presented && events_) events_({frame, {status, why}});
}

void FrameAssembler::drop(std::uint64_t frame, const std::string& why) {
  const auto it = open_.find(frame);
  if (it == open_.end()) return;
  const long long covered = it->second.coveredPixels;
  heldBytes_ -= it->second.heldBytes;
  open_.erase(it);
  char share[64];
  std::snprintf(share, sizeof share,
                limits_.wholeScreen ? " (%.1f%% of screen pixels arrived)"
                                    : " (%.1f%% of display pixels arrived)",
                100.0 * double(covered) / double(std::max<long long>(1, neededPixels_)));
  report(frame, net::FrameStatus::Dropped, why + share);
}

void FrameAssembler::startSequence(std::uint64_t firstFrame, const std::string& why) {
  while (!open_.empty()) drop(open_.begin()->first, why);
  firstFrame_ = firstFrame;
  lastComplete_.reset();
  reported_.clear();
}

bool FrameAssembler::supersede(std::uint64_t frame, const std::string& why) {
  if (reported(frame) || outsideWindow(frame)) return false;
  if (const auto it = open_.find(frame); it != open_.end()) {
    heldBytes_ -= it->second.heldBytes;
    open_.erase(it);
  } else {
    // Not open: one the job may have in flight with no tile sent yet, at most pendingFrames
    // after the last complete frame (or the first); further ahead it is no frame of the job's.
    const std::uint64_t next = lastComplete_ ? *lastComplete_ + 1 : firstFrame_;
    if (frame - next >= std::uint64_t(limits_.pendingFrames)) return false;
  }
  report(frame, net::FrameStatus::Superseded, why);
  return true;
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

voxwall::Rect FrameAssembler::screenRect(const net::TileMessage& tile,
                                         const std::string& peer) const {
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
  return net::fullScreenRect(sent, step, wall_.width, wall_.height);
}

std::uint64_t FrameAssembler::tileCost(const net::TileMessage& tile,
                                       const voxwall::Rect& screen) const {
  // Ranks cut their segments at the display edges the Welcome names, so a segment goes to one
  // display's page; one that straddles edges is copied to each (800 overlapping segments of
  // 61.6 MB went out as 246.7 MB a frame when this was not counted).
  const auto touched = std::count_if(wall_.displays.begin(), wall_.displays.end(),
                                     [&](const Display& d) { return screen.overlaps(d.rect); });
  return tile.bytes.size() * std::uint64_t(std::max<std::ptrdiff_t>(1, touched)) + sizeof(Segment);
}

void FrameAssembler::checkOverlap(std::uint64_t frame, const net::TileMessage& tile,
                                  std::uint64_t sentBefore, const std::string& peer) const {
  const std::uint64_t screen = std::uint64_t(net::reducedSide(wall_.width, tile.step)) *
                               std::uint64_t(net::reducedSide(wall_.height, tile.step));
  if (sentBefore + std::uint64_t(tile.rect.area()) > 2 * screen)
    throw FormatError(peer, "the tiles of frame " + std::to_string(frame) +
                                " cover its screen more than twice over (overlapping segments)");
}

bool FrameAssembler::makeRoom(std::uint64_t frame, std::uint64_t need) {
  while (heldBytes_ + need > limits_.pendingBytes) {
    auto victim = open_.begin();
    if (victim != open_.end() && victim->first == frame) ++victim;
    if (victim == open_.end()) {  // this frame alone holds too much (overlapping tiles)
      drop(frame, "over the sink's memory limit for open frames");
      return false;
    }
    drop(victim->first, "over the sink's memory limit for open frames");
  }
  return true;
}

FrameAssembler::Open& FrameAssembler::openFrame(std::uint64_t frame, const net::TileMessage& tile) {
  auto it = open_.find(frame);
  if (it != open_.end()) return it->second;
  while (int(open_.size()) >= limits_.pendingFrames)
    drop(open_.begin()->first, "too many frames open");
  it = open_.emplace(frame, Open{}).first;
  it->second.covered.assign(coverageBytes_ / 8, 0);
  it->second.heldBytes = coverageBytes_;
  it->second.info.frame = frame;
  it->second.info.step = tile.step;
  it->second.info.phase = tile.phase;
  heldBytes_ += coverageBytes_;
  return it->second;
}

AssembledFrame FrameAssembler::complete(std::uint64_t frame) {
  // Older frames can never be shown now, and frames far ahead are bogus.
  while (open_.begin()->first != frame) drop(open_.begin()->first, "a newer frame completed");
  Open& f = open_.begin()->second;
  AssembledFrame done = std::move(f.info);
  heldBytes_ -= f.heldBytes;
  open_.erase(open_.begin());
  lastComplete_ = frame;
  report(frame, net::FrameStatus::Presented, "");
  while (!open_.empty() && open_.rbegin()->first - frame > limits_.frameWindow)
    drop(open_.rbegin()->first, "outside the frame window after frame " + std::to_string(frame));
  return done;
}

std::optional<AssembledFrame> FrameAssembler::addTile(std::uint64_t frame, net::TileMessage tile,
                                                      int rank, const std::string& peer) {
  const voxwall::Rect r = screenRect(tile, peer);
  const auto it = open_.find(frame);
  const bool opened = it != open_.end();
  if (opened && it->second.info.step != tile.step)
    throw FormatError(peer, "tile of frame " + std::to_string(frame) + " at step " +
                                std::to_string(tile.step) + ", its other tiles are at step " +
                                std::to_string(it->second.info.step));
  if (!opened) {
    if (reported(frame)) return std::nullopt;  // settled; its fate was reported
    if (const auto why = outsideWindow(frame)) {
      report(frame, net::FrameStatus::Refused, "frame id " + std::to_string(frame) + " is " + *why);
      return std::nullopt;
    }
  }
  // Check before touching the frame: a tile whose header disagrees with its rectangle must not
  // mark any pixel as arrived.
  net::checkTile(tile.bytes, tile.codec, tile.rect.width, tile.rect.height, peer);
  checkOverlap(frame, tile, opened ? it->second.sentPixels : 0, peer);
  // Make room first: what a tile costs is its bytes, once per display they go to.
  const std::uint64_t tileBytes = tileCost(tile, r);
  if (!makeRoom(frame, tileBytes + (opened ? 0 : coverageBytes_))) return std::nullopt;
  Open& f = openFrame(frame, tile);
  f.sentPixels += std::uint64_t(tile.rect.area());
  cover(f, r);
  f.heldBytes += tileBytes;
  heldBytes_ += tileBytes;
  auto& info = f.info;
  info.bytes += tile.bytes.size();
  info.segments.push_back({tile.rect, r, tile.codec,
                           std::make_shared<const std::vector<std::byte>>(std::move(tile.bytes)),
                           rank});
  info.rankRenderMicros[rank] = tile.renderMicros;
  info.decidedUnixMicros = info.decidedUnixMicros
                               ? std::min(info.decidedUnixMicros, tile.decidedUnixMicros)
                               : tile.decidedUnixMicros;
  ++info.tiles;
  if (f.coveredPixels < neededPixels_) return std::nullopt;
  return complete(frame);
}

}  // namespace voxwall::walls
