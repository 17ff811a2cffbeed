// What the web view (web_view.hpp) sends, as pure functions: the descriptions of the wall and of
// a display, the list of displays with their launch lines, and the frame messages of the display
// pages (segments as the ranks sent them) and of the overview (the frame decoded scaled down).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <voxwall/walls/frame_assembler.hpp>
#include <voxwall/walls/wall.hpp>
#include <voxwall/walls/web_view.hpp>

namespace voxwall::walls::web {

// {"type":"wall", ...} for the overview page.
std::string wallJson(const Wall& wall, bool token);
// {"type":"display", ...} for the page of `display`.
std::string displayJson(const Wall& wall, const Display& display, bool token, int swapTimeoutMs);
// The display list: `base` is what the browser asked for ("http://HOST:PORT"), escaped here.
std::string displaysJson(const Wall& wall, const std::string& base);
std::string displaysHtml(const Wall& wall, const std::string& base, bool token);
// The shell line that opens `display`'s page full screen in a kiosk browser of its own.
std::string launchLine(const std::string& base, const std::string& display);

// A display page's frame: every segment that touches the display, bytes as received. `seq` is
// the sink's count of presented frames: pages answer with it (frame ids restart with each job).
std::shared_ptr<const std::string> displayFrameMessage(const AssembledFrame& frame,
                                                       const Display& display, std::uint64_t seq,
                                                       double latencyMs);
// The overview's frame: decoded at 1/k (k the smallest whole factor that fits maxWidth) and
// JPEG-compressed, with the load balancer's rectangles and the sink's numbers.
std::shared_ptr<const std::string> overviewFrameMessage(const ViewerFrame& frame, const Wall& wall,
                                                        int maxWidth, int jpegQuality);

// A Host header's value as RFC 3986's authority: host [":" port], the host an IP literal in
// brackets, or a name or IPv4 address of letters, digits, '.', '-', '_' and '~'; the port 0 to
// 65535 (or empty). Returns the host (lower case; brackets kept), nothing when malformed
// ("[::1]evil.example", "127.0.0.1:evil").
std::optional<std::string> hostOfAuthority(std::string_view authority);

// "/display/<name>" -> the display's index in `wall` (the name percent-decoded); nullopt when
// the path is not a display's.
std::optional<std::size_t> displayOfPath(const Wall& wall, std::string_view path,
                                         std::string_view prefix);

}  // namespace voxwall::walls::web
