// libFuzzer target for the frame-loop messages (master/frame_messages.hpp): the first byte picks
// the decoder, the rest is the message. Decoders must throw FormatError or return a message that
// keeps every promise (rectangles on the screen, pixel counts matching); anything else is a bug.
#include <cstdint>
#include <cstdlib>
#include <voxwall/core/errors.hpp>
#include <voxwall/master/frame_messages.hpp>

using namespace voxwall;

namespace {

master::FrameTask fixedTask() {
  master::FrameTask t;
  t.frame = 3;
  t.screenWidth = 40, t.screenHeight = 30;
  t.cellPixels = 8;
  t.rects = {{{0, 0, 40, 15}}, {{0, 15, 20, 15}, {20, 15, 20, 15}}};
  return t;
}

void check(bool ok) {
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::span bytes(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  try {
    if (data[0] & 1) {
      const auto task = fixedTask();
      const auto r = master::decodeRankReport(bytes, task, "fuzz");
      for (const auto& t : r.tiles) {
        check(t.rect.x >= 0 && t.rect.y >= 0 && t.rect.x + t.rect.width <= task.screenWidth &&
              t.rect.y + t.rect.height <= task.screenHeight);
        // A report without pixels (the rank streamed them, or nobody asked) carries rectangles
        // only; the master pastes tiles only when the pixel flag is set.
        const std::size_t n = std::size_t(t.rect.width) * std::size_t(t.rect.height);
        check(t.image.pixels.size() == (r.pixels ? n : 0));
      }
      check(r.costs.seconds.size() == std::size_t(r.costs.cellsX) * std::size_t(r.costs.cellsY));
    } else {
      const auto t = master::decodeFrameTask(bytes, "fuzz");
      for (const auto& rects : t.rects)
        for (const auto& r : rects)
          check(r.width > 0 && r.height > 0 && r.x + r.width <= t.screenWidth &&
                r.y + r.height <= t.screenHeight);
      // What decodes must encode to the same bytes.
      const auto again = master::encode(t);
      check(again.size() == bytes.size());
    }
  } catch (const FormatError&) {
  }
  return 0;
}
