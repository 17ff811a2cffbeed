#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <pugixml.hpp>
#include <set>
#include <sstream>
#include <voxwall/core/errors.hpp>
#include <voxwall/walls/wall.hpp>

namespace voxwall::walls {
namespace {

using nlohmann::json;

int intField(const json& j, const char* key, const std::string& source, int fallback = -1) {
  if (!j.contains(key)) {
    if (fallback >= 0) return fallback;
    throw FormatError(source, std::string("missing \"") + key + "\"");
  }
  if (!j[key].is_number_integer())
    throw FormatError(source, std::string("\"") + key + "\" must be an integer");
  const auto v = j[key].get<long long>();
  if (v < -kMaxScreenSide || v > kMaxScreenSide)
    throw FormatError(source,
                      std::string("\"") + key + "\" = " + std::to_string(v) + " is out of range");
  return int(v);
}

double numberField(const json& j, const char* key, const std::string& source, double fallback) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_number() || !std::isfinite(j[key].get<double>()) || j[key].get<double>() < 0)
    throw FormatError(source, std::string("\"") + key + "\" must be a non-negative number");
  return j[key].get<double>();
}

Wall gridWall(std::string id, int w, int h, int columns, int rows, int gapX, int gapY) {
  if (w <= 0 || h <= 0 || columns <= 0 || rows <= 0 || gapX < 0 || gapY < 0)
    throw std::invalid_argument("grid");
  Wall wall;
  wall.id = std::move(id);
  wall.width = columns * w + (columns - 1) * gapX;
  wall.height = rows * h + (rows - 1) * gapY;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < columns; ++c) {
      // Named rRcC (row, column), counted from the top left.
      std::string name = "r";
      name += std::to_string(r);
      name += 'c';
      name += std::to_string(c);
      wall.displays.push_back({name, {c * (w + gapX), r * (h + gapY), w, h}});
    }
  return wall;
}

glm::dvec3 parseColor(const json& j, const std::string& source) {
  if (j.is_array() && j.size() == 3) {
    glm::dvec3 c;
    for (int i = 0; i < 3; ++i) {
      if (!j[i].is_number() || j[i].get<double>() < 0 || j[i].get<double>() > 1)
        throw FormatError(source, "\"background\" must be [r, g, b] in [0, 1]");
      c[i] = j[i].get<double>();
    }
    return c;
  }
  if (j.is_string()) {  // "#rrggbb", as Tide writes it
    const auto s = j.get<std::string>();
    unsigned v = 0;
    if (s.size() == 7 && s[0] == '#' && std::sscanf(s.c_str() + 1, "%6x", &v) == 1)
      return glm::dvec3((v >> 16) & 255, (v >> 8) & 255, v & 255) / 255.0;
  }
  throw FormatError(source, "\"background\" must be [r, g, b] in [0, 1] or \"#rrggbb\"");
}

// One surface of a Tide configuration, with Tide's geometry (its SurfaceConfig): a screen is
// displaysPerScreenX x displaysPerScreenY displays, and bezels (possibly negative: overlapping
// displays) separate neighbouring displays inside a screen and neighbouring screens alike.
struct TideSurface {
  int displayWidth = 0, displayHeight = 0;
  int displaysPerScreenX = 1, displaysPerScreenY = 1;
  int screenCountX = 1, screenCountY = 1;
  int bezelWidth = 0, bezelHeight = 0;
  std::optional<glm::dvec3> background;
};

// Checks a surface's numbers; `field(name)` says where a field is ("f.json: surfaces[1].x").
void checkTideSurface(const TideSurface& t, const std::function<std::string(const char*)>& field) {
  auto atLeast = [&](int value, int least, const char* name) {
    if (value < least)
      throw FormatError(field(name),
                        std::to_string(value) + ", must be at least " + std::to_string(least));
  };
  atLeast(t.displayWidth, 1, "displayWidth");
  atLeast(t.displayHeight, 1, "displayHeight");
  atLeast(t.displaysPerScreenX, 1, "displaysPerScreenX");
  atLeast(t.displaysPerScreenY, 1, "displaysPerScreenY");
  atLeast(t.screenCountX, 1, "screenCountX");
  atLeast(t.screenCountY, 1, "screenCountY");
  if (t.displayWidth > kMaxDisplaySide) throw FormatError(field("displayWidth"), "too large");
  if (t.displayHeight > kMaxDisplaySide) throw FormatError(field("displayHeight"), "too large");
  // A negative bezel overlaps neighbours; it cannot swallow a whole display.
  if (t.bezelWidth <= -t.displayWidth || t.bezelWidth > kMaxDisplaySide)
    throw FormatError(field("bezelWidth"), std::to_string(t.bezelWidth) +
                                               ": neighbours would not advance (displayWidth " +
                                               std::to_string(t.displayWidth) + ")");
  if (t.bezelHeight <= -t.displayHeight || t.bezelHeight > kMaxDisplaySide)
    throw FormatError(field("bezelHeight"), std::to_string(t.bezelHeight) +
                                                ": neighbours would not advance (displayHeight " +
                                                std::to_string(t.displayHeight) + ")");
  const long long displays =
      (long long)t.displaysPerScreenX * t.displaysPerScreenY * t.screenCountX * t.screenCountY;
  if (t.displaysPerScreenX > kMaxDisplays || t.displaysPerScreenY > kMaxDisplays ||
      t.screenCountX > kMaxDisplays || t.screenCountY > kMaxDisplays || displays > kMaxDisplays)
    throw FormatError(field("screenCountX"), "the surface has " + std::to_string(displays) +
                                                 " displays, at most " +
                                                 std::to_string(kMaxDisplays));
}

Wall tideWall(const TideSurface& t, int index, const std::string& where) {
  const int columns = t.displaysPerScreenX * t.screenCountX;
  const int rows = t.displaysPerScreenY * t.screenCountY;
  // Display n of a row starts at n * (displayWidth + bezelWidth): inside a screen and across
  // screens the step is the same, which is Tide's screen width plus one bezel per screen.
  const long long stepX = t.displayWidth + t.bezelWidth, stepY = t.displayHeight + t.bezelHeight;
  const long long width = columns * stepX - t.bezelWidth, height = rows * stepY - t.bezelHeight;
  if (width > kMaxScreenSide || height > kMaxScreenSide)
    throw FormatError(where, "surface of " + std::to_string(width) + "x" + std::to_string(height) +
                                 " pixels is beyond the limit (" + std::to_string(kMaxScreenSide) +
                                 " per side)");
  Wall wall;
  wall.id = "tide-surface" + std::to_string(index);
  wall.width = int(width), wall.height = int(height);
  wall.overlapping = t.bezelWidth < 0 || t.bezelHeight < 0;
  const bool oneDisplayPerScreen = t.displaysPerScreenX == 1 && t.displaysPerScreenY == 1;
  for (int row = 0; row < rows; ++row)
    for (int column = 0; column < columns; ++column) {
      // Named by screen (i, j: column and row of the screen, as Tide counts them) and, with
      // several displays per screen, by the display's column and row inside it.
      const int i = column / t.displaysPerScreenX, j = row / t.displaysPerScreenY;
      // (Appended piece by piece: g++ 12 warns falsely (-Wrestrict) on "s" + to_string(i).)
      std::string name = "s";
      name += std::to_string(i);
      name += '-';
      name += std::to_string(j);
      if (!oneDisplayPerScreen) {
        name += "_d";
        name += std::to_string(column % t.displaysPerScreenX);
        name += '-';
        name += std::to_string(row % t.displaysPerScreenY);
      }
      wall.displays.push_back(
          {name, {int(column * stepX), int(row * stepY), t.displayWidth, t.displayHeight}});
    }
  if (t.background) wall.background = *t.background;
  char text[256];
  std::snprintf(text, sizeof text,
                "Tide surface %d: %dx%d screens of %dx%d displays of %dx%d, bezels %d,%d px%s",
                index, t.screenCountX, t.screenCountY, t.displaysPerScreenX, t.displaysPerScreenY,
                t.displayWidth, t.displayHeight, t.bezelWidth, t.bezelHeight,
                wall.overlapping ? " (overlapping displays)" : "");
  wall.description = text;
  return wall;
}

std::vector<Wall> parseTide(const json& doc, const std::string& source) {
  const json& surfaces = doc["surfaces"];
  if (!surfaces.is_array() || surfaces.empty())
    throw FormatError(source, "\"surfaces\" must be a non-empty array");
  std::optional<glm::dvec3> globalBackground;
  if (doc.contains("background") && doc["background"].is_object() &&
      doc["background"].contains("color"))
    globalBackground = parseColor(doc["background"]["color"], source + ": background.color");
  std::vector<Wall> walls;
  for (std::size_t n = 0; n < surfaces.size(); ++n) {
    const std::string where = source + ": surfaces[" + std::to_string(n) + "]";
    const json& s = surfaces[n];
    if (!s.is_object()) throw FormatError(where, "must be an object");
    auto field = [&](const char* name) { return where + "." + name; };
    auto number = [&](const char* name, std::optional<int> fallback) {
      if (!s.contains(name)) {
        if (fallback) return *fallback;
        throw FormatError(where, std::string("missing \"") + name + "\"");
      }
      if (!s[name].is_number_integer()) throw FormatError(field(name), "must be an integer");
      const auto v = s[name].get<long long>();
      if (v < -kMaxScreenSide || v > kMaxScreenSide)
        throw FormatError(field(name), std::to_string(v) + " is out of range");
      return int(v);
    };
    TideSurface t;
    t.displayWidth = number("displayWidth", std::nullopt);
    t.displayHeight = number("displayHeight", std::nullopt);
    t.displaysPerScreenX = number("displaysPerScreenX", 1);
    t.displaysPerScreenY = number("displaysPerScreenY", 1);
    t.screenCountX = number("screenCountX", 1);
    t.screenCountY = number("screenCountY", 1);
    t.bezelWidth = number("bezelWidth", 0);
    t.bezelHeight = number("bezelHeight", 0);
    t.background = globalBackground;
    if (s.contains("background") && s["background"].is_object() &&
        s["background"].contains("color"))
      t.background = parseColor(s["background"]["color"], field("background.color"));
    checkTideSurface(t, field);
    walls.push_back(tideWall(t, int(n), where));
  }
  return walls;
}

// Tide's XML configuration (its older form, still read by Tide):
//   <configuration><dimensions numScreensX=".." numScreensY=".." displayWidth=".."
//     displayHeight=".." bezelWidth=".." bezelHeight=".." displaysPerScreenX=".."
//     displaysPerScreenY=".."/><background color="#rrggbb"/>...</configuration>
// One surface. Before Tide 1.4 the keys were numTilesWidth/Height, screenWidth/Height and
// mullionWidth/Height (one display per screen); those are read too.
std::vector<Wall> parseTideXml(const std::string& text, const std::string& source) {
  pugi::xml_document doc;
  const auto parsed = doc.load_buffer(text.data(), text.size());
  if (!parsed)
    throw FormatError(source, std::string("not valid XML: ") + parsed.description() + " at byte " +
                                  std::to_string(parsed.offset));
  const auto configuration = doc.child("configuration");
  if (!configuration) throw FormatError(source, "no <configuration> element");
  const auto dimensions = configuration.child("dimensions");
  if (!dimensions) throw FormatError(source, "no <dimensions> element in <configuration>");
  auto field = [&](const char* name) { return source + ": dimensions@" + std::string(name); };
  auto number = [&](std::initializer_list<const char*> names, std::optional<int> fallback) {
    for (const char* name : names) {
      const auto attribute = dimensions.attribute(name);
      if (!attribute) continue;
      const std::string value = attribute.value();
      std::size_t used = 0;
      long long v = 0;
      try {
        v = std::stoll(value, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != value.size() || v < -kMaxScreenSide || v > kMaxScreenSide)
        throw FormatError(field(name), "'" + value + "' is not an integer in range");
      return int(v);
    }
    if (fallback) return *fallback;
    throw FormatError(source, std::string("<dimensions> has no ") + *names.begin());
  };
  TideSurface t;
  t.displayWidth = number({"displayWidth", "screenWidth"}, std::nullopt);
  t.displayHeight = number({"displayHeight", "screenHeight"}, std::nullopt);
  t.displaysPerScreenX = number({"displaysPerScreenX"}, 1);
  t.displaysPerScreenY = number({"displaysPerScreenY"}, 1);
  t.screenCountX = number({"numScreensX", "numTilesWidth"}, 1);
  t.screenCountY = number({"numScreensY", "numTilesHeight"}, 1);
  t.bezelWidth = number({"bezelWidth", "mullionWidth"}, 0);
  t.bezelHeight = number({"bezelHeight", "mullionHeight"}, 0);
  if (const auto color = configuration.child("background").attribute("color"))
    t.background = parseColor(json(std::string(color.value())), source + ": background@color");
  checkTideSurface(t, field);
  return {tideWall(t, 0, source)};
}

// A wall whose "displays" are listed, each with its rectangle.
Wall listedDisplays(const json& doc, const std::string& id, const std::string& source) {
  const json& list = doc["displays"];
  if (!list.is_array() || list.empty())
    throw FormatError(source, "\"displays\" must be a non-empty array");
  if (list.size() > std::size_t(kMaxDisplays))
    throw FormatError(
        source, std::to_string(list.size()) + " displays, at most " + std::to_string(kMaxDisplays));
  Wall wall;
  wall.id = id;
  int right = 0, bottom = 0;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = source + ": displays[" + std::to_string(i) + "]";
    if (!list[i].is_object()) throw FormatError(where, "must be an object");
    Display d;
    d.name = list[i].contains("name") && list[i]["name"].is_string()
                 ? list[i]["name"].get<std::string>()
                 : "d" + std::to_string(i);
    d.rect = {intField(list[i], "x", where), intField(list[i], "y", where),
              intField(list[i], "width", where), intField(list[i], "height", where)};
    right = std::max(right, d.rect.x + d.rect.width);
    bottom = std::max(bottom, d.rect.y + d.rect.height);
    wall.displays.push_back(d);
  }
  if (doc.contains("size")) {
    const json& size = doc["size"];
    if (!size.is_array() || size.size() != 2 || !size[0].is_number_integer() ||
        !size[1].is_number_integer())
      throw FormatError(source, "\"size\" must be [width, height]");
    wall.width = size[0].get<int>(), wall.height = size[1].get<int>();
  } else {
    wall.width = right, wall.height = bottom;
  }
  return wall;
}

// The gaps between a grid's displays in pixels: "bezel_px", or "bezel_mm" at the display's pixel
// pitch (its "width_mm" and "height_mm").
std::pair<int, int> gridGaps(const json& doc, int w, int h, const std::string& source) {
  if (doc.contains("bezel_px"))
    return {intField(doc["bezel_px"], "x", source + ": bezel_px", 0),
            intField(doc["bezel_px"], "y", source + ": bezel_px", 0)};
  if (!doc.contains("bezel_mm")) return {0, 0};
  const json& d = doc["display"];
  const json& b = doc["bezel_mm"];
  const double widthMm = numberField(d, "width_mm", source + ": display", 0);
  const double heightMm = numberField(d, "height_mm", source + ": display", 0);
  if (!(widthMm > 0) || !(heightMm > 0) || w <= 0 || h <= 0)
    throw FormatError(source,
                      "\"bezel_mm\" needs the display's \"width_mm\" and "
                      "\"height_mm\" (for the pixel pitch)");
  const std::string where = source + ": bezel_mm";
  const double left = numberField(b, "left", where, 0), right = numberField(b, "right", where, 0);
  const double top = numberField(b, "top", where, 0), bottom = numberField(b, "bottom", where, 0);
  return {int(std::lround((left + right) / (widthMm / w))),
          int(std::lround((top + bottom) / (heightMm / h)))};
}

// A wall of equal displays in a "grid" of columns and rows, with bezels between them.
Wall gridDisplays(const json& doc, const std::string& id, const std::string& source) {
  if (!doc.contains("display") || !doc["display"].is_object() || !doc.contains("grid") ||
      !doc["grid"].is_object())
    throw FormatError(source, "needs \"display\" and \"grid\", or \"displays\"");
  const json& d = doc["display"];
  const int w = intField(d, "width", source + ": display");
  const int h = intField(d, "height", source + ": display");
  const int columns = intField(doc["grid"], "columns", source + ": grid");
  const int rows = intField(doc["grid"], "rows", source + ": grid");
  const auto [gapX, gapY] = gridGaps(doc, w, h, source);
  if (w <= 0 || h <= 0 || columns <= 0 || rows <= 0 || gapX < 0 || gapY < 0 ||
      gapX > kMaxDisplaySide || gapY > kMaxDisplaySide)
    throw FormatError(source, "display size and grid must be positive, bezels not negative");
  if ((long long)columns * rows > kMaxDisplays)
    throw FormatError(source, std::to_string((long long)columns * rows) + " displays, at most " +
                                  std::to_string(kMaxDisplays));
  return gridWall(id, w, h, columns, rows, gapX, gapY);
}

Wall parseVoxwall(const json& doc, const std::string& source) {
  const std::string id =
      doc.contains("wall") && doc["wall"].is_string() ? doc["wall"].get<std::string>() : "wall";
  Wall wall =
      doc.contains("displays") ? listedDisplays(doc, id, source) : gridDisplays(doc, id, source);
  if (doc.contains("background")) wall.background = parseColor(doc["background"], source);
  if (doc.contains("overlap")) {
    if (!doc["overlap"].is_boolean())
      throw FormatError(source, "\"overlap\" must be true or false");
    wall.overlapping = doc["overlap"].get<bool>();
  }
  return wall;
}

}  // namespace

long long Wall::displayPixels() const {
  long long n = 0;
  if (!overlapping) {
    for (const auto& d : displays) n += d.rect.area();
    return n;
  }
  // The union: per band between neighbouring top/bottom edges, the merged x-intervals.
  std::vector<int> edges;
  for (const auto& d : displays)
    edges.push_back(d.rect.y), edges.push_back(d.rect.y + d.rect.height);
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  std::vector<std::pair<int, int>> spans;
  for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
    spans.clear();
    for (const auto& d : displays)
      if (d.rect.y <= edges[b] && edges[b + 1] <= d.rect.y + d.rect.height)
        spans.emplace_back(d.rect.x, d.rect.x + d.rect.width);
    std::sort(spans.begin(), spans.end());
    long long covered = 0;
    int end = std::numeric_limits<int>::min();
    for (const auto& [from, to] : spans) {
      if (to <= end) continue;
      covered += to - std::max(from, end);
      end = to;
    }
    n += covered * (edges[b + 1] - edges[b]);
  }
  return n;
}

void validateWall(const Wall& wall, const std::string& source) {
  if (wall.width <= 0 || wall.height <= 0 || wall.width > kMaxScreenSide ||
      wall.height > kMaxScreenSide || (long long)wall.width * wall.height > kMaxScreenPixels)
    throw FormatError(source, "virtual screen " + std::to_string(wall.width) + "x" +
                                  std::to_string(wall.height) + " is empty or beyond the limit (" +
                                  std::to_string(kMaxScreenSide) + " per side, 2^30 pixels)");
  if (wall.displays.empty()) throw FormatError(source, "no displays");
  if (wall.displays.size() > std::size_t(kMaxDisplays))
    throw FormatError(source, "more than " + std::to_string(kMaxDisplays) + " displays");
  std::set<std::string> names;
  for (std::size_t i = 0; i < wall.displays.size(); ++i) {
    const auto& d = wall.displays[i];
    const auto& r = d.rect;
    const std::string what = "display '" + d.name + "'";
    if (r.width <= 0 || r.height <= 0 || r.width > kMaxDisplaySide || r.height > kMaxDisplaySide)
      throw FormatError(
          source, what + " has size " + std::to_string(r.width) + "x" + std::to_string(r.height));
    if (!r.fitsIn(wall.width, wall.height))
      throw FormatError(source, what + " lies outside the " + std::to_string(wall.width) + "x" +
                                    std::to_string(wall.height) + " screen");
    if (d.name.empty() || d.name.size() > 64 ||
        d.name.find_first_of("/\\ \t\n") != std::string::npos)
      throw FormatError(source, what + ": names are 1-64 characters, no slashes or spaces");
    if (!names.insert(d.name).second) throw FormatError(source, what + " is named twice");
    if (wall.overlapping) continue;
    for (std::size_t k = 0; k < i; ++k) {
      const auto& o = wall.displays[k].rect;
      if (r.overlaps(o))
        throw FormatError(source, what + " overlaps display '" + wall.displays[k].name +
                                      "' (if they really overlap, as edge-blended projectors "
                                      "do, say \"overlap\": true)");
    }
  }
}

std::vector<Wall> parseWalls(const std::string& text, const std::string& source) {
  const auto first = text.find_first_not_of(" \t\r\n");
  std::vector<Wall> walls;
  if (first != std::string::npos && text[first] == '<') {
    walls = parseTideXml(text, source);
  } else {
    json doc;
    try {
      doc = json::parse(text);
    } catch (const json::exception& e) {
      throw FormatError(source, std::string("not valid JSON: ") + e.what());
    }
    if (!doc.is_object()) throw FormatError(source, "a wall file is a JSON object");
    if (doc.contains("surfaces"))
      walls = parseTide(doc, source);
    else
      walls.push_back(parseVoxwall(doc, source));
  }
  for (std::size_t n = 0; n < walls.size(); ++n)
    validateWall(walls[n],
                 walls.size() > 1 ? source + ": surfaces[" + std::to_string(n) + "]" : source);
  return walls;
}

Wall selectSurface(std::vector<Wall> walls, int surface, const std::string& source) {
  if (surface < 0 || std::size_t(surface) >= walls.size())
    throw FormatError(source, "--surface " + std::to_string(surface) + ": the file has " +
                                  std::to_string(walls.size()) + " surface(s), 0 to " +
                                  std::to_string(walls.size() - 1));
  return std::move(walls[std::size_t(surface)]);
}

Wall parseWall(const std::string& text, const std::string& source, int surface) {
  return selectSurface(parseWalls(text, source), surface, source);
}

std::vector<Wall> loadWalls(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw FormatError(path, "cannot open wall file");
  std::stringstream text;
  text << in.rdbuf();
  return parseWalls(text.str(), path);
}

Wall loadWall(const std::string& path, int surface) {
  return selectSurface(loadWalls(path), surface, path);
}

std::string describeSurface(const Wall& wall, int index) {
  char line[512];
  std::snprintf(line, sizeof line, "surface %d: %zu display(s), virtual screen %dx%d%s%s", index,
                wall.displays.size(), wall.width, wall.height,
                wall.description.empty() ? "" : " - ", wall.description.c_str());
  return line;
}

Wall singleDisplayWall(int width, int height) {
  Wall wall;
  wall.id = "screen";
  wall.width = width, wall.height = height;
  wall.displays.push_back({"screen", {0, 0, width, height}});
  validateWall(wall, "--size");
  return wall;
}

}  // namespace voxwall::walls
