#include "web_messages.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/walls/frame_pixels.hpp>

namespace voxwall::walls::web {

namespace {

// Binary WebSocket messages: u32 length of the JSON (little-endian), the JSON, then bytes.
std::string withHeader(const std::string& json, std::size_t extra) {
  std::string message;
  message.reserve(4 + json.size() + extra);
  const auto n = std::uint32_t(json.size());
  const char length[4] = {char(n & 0xff), char((n >> 8) & 0xff), char((n >> 16) & 0xff),
                          char((n >> 24) & 0xff)};
  message.append(length, 4);
  message.append(json);
  return message;
}

std::string htmlEscape(const std::string& text) {
  std::string out;
  for (const char c : text) switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  return out;
}

// Percent-encodes everything but RFC 3986's unreserved characters: safe in a URL, a path and a
// shell word alike.
std::string urlEncode(const std::string& text) {
  std::string out;
  for (const unsigned char c : text) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
      out += char(c);
    } else {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", c);
      out += hex;
    }
  }
  return out;
}

std::string colourHex(const glm::dvec3& c) {
  char hex[8];
  const auto p = backgroundPixel(c);
  std::snprintf(hex, sizeof hex, "#%02x%02x%02x", p & 255u, (p >> 8) & 255u, (p >> 16) & 255u);
  return hex;
}

nlohmann::json rectJson(const voxwall::Rect& r) {
  return {{"x", r.x}, {"y", r.y}, {"w", r.width}, {"h", r.height}};
}

struct Placement {
  voxwall::Rect rect;
  int rank = 0;
};

// A rank's tiles arrive in segments (cut at display edges and every 1024 pixels): joins the
// segments of one rank that share an edge whole, so the overlay shows the rectangles the
// balancer cut.
std::vector<Placement> mergePlacements(std::vector<Placement> tiles) {
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < tiles.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < tiles.size() && !merged; ++j) {
        auto &a = tiles[i].rect, &b = tiles[j].rect;
        if (tiles[i].rank != tiles[j].rank) continue;
        if (a.x == b.x && a.width == b.width && (a.y + a.height == b.y || b.y + b.height == a.y)) {
          a = {a.x, std::min(a.y, b.y), a.width, a.height + b.height};
          merged = true;
        } else if (a.y == b.y && a.height == b.height &&
                   (a.x + a.width == b.x || b.x + b.width == a.x)) {
          a = {std::min(a.x, b.x), a.y, a.width + b.width, a.height};
          merged = true;
        }
        if (merged) tiles.erase(tiles.begin() + std::ptrdiff_t(j));
      }
  }
  return tiles;
}

}  // namespace

std::string wallJson(const Wall& wall, bool token) {
  nlohmann::json w = {{"type", "wall"},
                      {"id", wall.id},
                      {"width", wall.width},
                      {"height", wall.height},
                      {"token", token}};
  auto& displays = w["displays"] = nlohmann::json::array();
  for (const auto& d : wall.displays) {
    auto j = rectJson(d.rect);
    j["name"] = d.name;
    displays.push_back(j);
  }
  return w.dump();
}

std::string displayJson(const Wall& wall, const Display& display, bool token, int swapTimeoutMs) {
  auto j = rectJson(display.rect);
  j["type"] = "display";
  j["name"] = display.name;
  j["wall"] = wall.id;
  j["token"] = token;
  j["swap_timeout_ms"] = swapTimeoutMs;
  j["background"] = colourHex(wall.background);
  return j.dump();
}

std::string launchLine(const std::string& base, const std::string& display) {
  const std::string name = urlEncode(display);
  return "chromium --kiosk --user-data-dir=/tmp/voxwall-display-" + name + " --app=" + base +
         "/display/" + name;
}

std::string displaysJson(const Wall& wall, const std::string& base) {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& d : wall.displays) {
    auto j = rectJson(d.rect);
    j["name"] = d.name;
    j["url"] = base + "/display/" + urlEncode(d.name);
    j["launch"] = launchLine(base, d.name);
    list.push_back(j);
  }
  return nlohmann::json{{"wall", wall.id}, {"displays", list}}.dump(2) + "\n";
}

std::string displaysHtml(const Wall& wall, const std::string& base, bool token) {
  std::string rows;
  for (const auto& d : wall.displays) {
    char size[64];
    std::snprintf(size, sizeof size, "%dx%d at %d,%d", d.rect.width, d.rect.height, d.rect.x,
                  d.rect.y);
    const std::string url = base + "/display/" + urlEncode(d.name);
    rows += "<tr><td><a href=\"" + htmlEscape(url) + "\">" + htmlEscape(d.name) + "</a></td><td>" +
            size + "</td><td><code>" + htmlEscape(launchLine(base, d.name)) + "</code></td></tr>\n";
  }
  return "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>voxwall: " +
         htmlEscape(wall.id) +
         " displays</title><style>body{font:14px system-ui,sans-serif;margin:2em;background:#111;"
         "color:#ddd}td{padding:2px 12px 2px 0;white-space:nowrap}a{color:#8cf}code{color:#fc8}"
         "</style></head>"
         "<body><h1>" +
         htmlEscape(wall.id) + ": " + std::to_string(wall.displays.size()) +
         " display(s)</h1><p>On each display's host, run its line (one browser per display; "
         "each with a profile of its own). The <a href=\"/\">overview</a> shows the whole wall." +
         (token ? " This wall asks for a token: add <code>#token=TOKEN</code> to the address "
                  "(it stays in the browser, it is not sent in the request)."
                : std::string()) +
         "</p><table><tr><th>display</th><th>pixels</th><th>launch line</th></tr>\n" + rows +
         "</table></body></html>\n";
}

std::shared_ptr<const std::string> displayFrameMessage(const AssembledFrame& frame,
                                                       const Display& display, std::uint64_t seq,
                                                       double latencyMs) {
  nlohmann::json meta = {{"type", "frame"},
                         {"frame", frame.frame},
                         {"seq", seq},
                         {"step", frame.step},
                         {"phase", frame.step > 1 && frame.phase != net::FramePhase::Refining
                                       ? "interactive"
                                       : net::phaseName(frame.phase)},
                         {"latency_ms", latencyMs}};
  auto& segments = meta["segments"] = nlohmann::json::array();
  std::size_t bytes = 0;
  std::vector<const Segment*> mine;
  for (const auto& s : frame.segments)
    if (s.screen.overlaps(display.rect)) {
      mine.push_back(&s);
      auto j = rectJson(s.rect);
      j["codec"] = net::tileCodecName(s.codec);
      j["bytes"] = s.bytes->size();
      segments.push_back(j);
      bytes += s.bytes->size();
    }
  auto message = std::make_shared<std::string>(withHeader(meta.dump(), bytes));
  for (const Segment* s : mine)
    message->append(reinterpret_cast<const char*>(s->bytes->data()), s->bytes->size());
  return message;
}

std::shared_ptr<const std::string> overviewFrameMessage(const ViewerFrame& f, const Wall& wall,
                                                        int maxWidth, int jpegQuality) {
  const AssembledFrame& frame = *f.frame;
  const int k = std::max(1, (wall.width + maxWidth - 1) / maxWidth);
  const voxwall::Image small =
      decodeRegion(frame, {0, 0, wall.width, wall.height}, k, backgroundPixel(wall.background), 2);
  net::TileCodecSettings codec;
  codec.codec = net::TileCodec::Jpeg;
  codec.jpegQuality = jpegQuality;
  codec.segmentPixels = std::max(small.width, small.height);
  codec.threads = 1;
  const auto parts =
      net::encodeTiles(small, {0, 0, small.width, small.height}, wall.background, codec);
  if (parts.size() != 1) return nullptr;
  nlohmann::json meta = {{"type", "frame"},
                         {"frame", frame.frame},
                         {"step", frame.step},
                         {"phase", frame.step > 1 && frame.phase != net::FramePhase::Refining
                                       ? "interactive"
                                       : net::phaseName(frame.phase)},
                         {"width", small.width},
                         {"height", small.height},
                         {"latency_ms", f.latencyMs},
                         {"bytes", frame.bytes},
                         {"presented", f.stats.framesPresented},
                         {"dropped", f.stats.framesDropped},
                         {"ranks_connected", f.stats.renderersConnected}};
  if (const auto& p = f.stats.playback)
    meta["time"] = {{"step", p->step},     {"first", p->first},     {"last", p->last},
                    {"stride", p->stride}, {"playing", p->playing}, {"rate", p->rate}};
  std::vector<Placement> placements;
  for (const auto& s : frame.segments) placements.push_back({s.screen, s.rank});
  auto& tiles = meta["tiles"] = nlohmann::json::array();
  for (const auto& t : mergePlacements(std::move(placements))) {
    auto j = rectJson(t.rect);
    j["rank"] = t.rank;
    tiles.push_back(j);
  }
  auto& ranks = meta["ranks"] = nlohmann::json::object();
  for (const auto& [rank, micros] : frame.rankRenderMicros)
    ranks[std::to_string(rank)] = double(micros) / 1e3;
  auto message = std::make_shared<std::string>(withHeader(meta.dump(), parts[0].bytes.size()));
  message->append(reinterpret_cast<const char*>(parts[0].bytes.data()), parts[0].bytes.size());
  return message;
}

std::optional<std::string> hostOfAuthority(std::string_view authority) {
  std::string host;
  std::string_view rest;
  if (authority.starts_with("[")) {
    const auto close = authority.find(']');
    if (close == std::string_view::npos || close < 2) return std::nullopt;
    for (const char c : authority.substr(1, close - 1))
      if (!std::isxdigit(static_cast<unsigned char>(c)) && c != ':' && c != '.')
        return std::nullopt;
    host = std::string(authority.substr(0, close + 1));
    rest = authority.substr(close + 1);
  } else {
    const auto colon = authority.find(':');
    host = std::string(authority.substr(0, colon));
    rest = colon == std::string_view::npos ? std::string_view() : authority.substr(colon);
    if (host.empty()) return std::nullopt;
    for (const char c : host)
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-' && c != '_' &&
          c != '~')
        return std::nullopt;
  }
  if (!rest.empty()) {
    const auto port = rest.substr(1);
    if (rest[0] != ':' || port.size() > 5) return std::nullopt;
    for (const char c : port)
      if (!std::isdigit(static_cast<unsigned char>(c))) return std::nullopt;
    if (!port.empty() && std::stoul(std::string(port)) > 65535) return std::nullopt;
  }
  for (char& c : host) c = char(std::tolower(static_cast<unsigned char>(c)));
  return host;
}

std::optional<std::size_t> displayOfPath(const Wall& wall, std::string_view path,
                                         std::string_view prefix) {
  if (!path.starts_with(prefix)) return std::nullopt;
  path.remove_prefix(prefix.size());
  std::string name;
  for (std::size_t i = 0; i < path.size(); ++i) {
    if (path[i] == '%' && i + 2 < path.size() && std::isxdigit((unsigned char)path[i + 1]) &&
        std::isxdigit((unsigned char)path[i + 2])) {
      name += char(std::stoi(std::string(path.substr(i + 1, 2)), nullptr, 16));
      i += 2;
    } else if (path[i] == '?' || path[i] == '#') {
      break;
    } else {
      name += path[i];
    }
  }
  for (std::size_t i = 0; i < wall.displays.size(); ++i)
    if (wall.displays[i].name == name) return i;
  return std::nullopt;
}

}  // namespace voxwall::walls::web
