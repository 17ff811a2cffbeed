#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
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

Wall parseTide(const json& doc, const std::string& source) {
  const json& surfaces = doc["surfaces"];
  if (!surfaces.is_array() || surfaces.empty() || !surfaces[0].is_object())
    throw FormatError(source, "Tide configuration without surfaces");
  const json& s = surfaces[0];
  const std::string where = source + ": surfaces[0]";
  Wall wall = [&] {
    const int w = intField(s, "displayWidth", where), h = intField(s, "displayHeight", where);
    const int cx = intField(s, "screenCountX", where, 1),
              cy = intField(s, "screenCountY", where, 1);
    const int bx = intField(s, "bezelWidth", where, 0), by = intField(s, "bezelHeight", where, 0);
    if (w <= 0 || h <= 0 || cx <= 0 || cy <= 0 || bx < 0 || by < 0 || cx > kMaxDisplays ||
        cy > kMaxDisplays)
      throw FormatError(where,
                        "display sizes and screen counts must be positive, bezels not "
                        "negative");
    if ((long long)cx * cy > kMaxDisplays)
      throw FormatError(where, std::to_string((long long)cx * cy) + " displays, at most " +
                                   std::to_string(kMaxDisplays));
    return gridWall("tide", w, h, cx, cy, bx, by);
  }();
  for (const json* b : {&doc, &s})
    if (b->contains("background") && (*b)["background"].is_object() &&
        (*b)["background"].contains("color"))
      wall.background = parseColor((*b)["background"]["color"], where);
  return wall;
}

Wall parseVoxwall(const json& doc, const std::string& source) {
  std::string id =
      doc.contains("wall") && doc["wall"].is_string() ? doc["wall"].get<std::string>() : "wall";
  Wall wall;
  if (doc.contains("displays")) {
    const json& list = doc["displays"];
    if (!list.is_array() || list.empty())
      throw FormatError(source, "\"displays\" must be a non-empty array");
    if (list.size() > std::size_t(kMaxDisplays))
      throw FormatError(source, std::to_string(list.size()) + " displays, at most " +
                                    std::to_string(kMaxDisplays));
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
  } else {
    if (!doc.contains("display") || !doc["display"].is_object() || !doc.contains("grid") ||
        !doc["grid"].is_object())
      throw FormatError(source, "needs \"display\" and \"grid\", or \"displays\"");
    const json& d = doc["display"];
    const int w = intField(d, "width", source + ": display");
    const int h = intField(d, "height", source + ": display");
    const int columns = intField(doc["grid"], "columns", source + ": grid");
    const int rows = intField(doc["grid"], "rows", source + ": grid");
    int gapX = 0, gapY = 0;
    if (doc.contains("bezel_px")) {
      gapX = intField(doc["bezel_px"], "x", source + ": bezel_px", 0);
      gapY = intField(doc["bezel_px"], "y", source + ": bezel_px", 0);
    } else if (doc.contains("bezel_mm")) {
      const json& b = doc["bezel_mm"];
      const double widthMm = numberField(d, "width_mm", source + ": display", 0);
      const double heightMm = numberField(d, "height_mm", source + ": display", 0);
      if (!(widthMm > 0) || !(heightMm > 0) || w <= 0 || h <= 0)
        throw FormatError(source,
                          "\"bezel_mm\" needs the display's \"width_mm\" and "
                          "\"height_mm\" (for the pixel pitch)");
      const std::string where = source + ": bezel_mm";
      const double left = numberField(b, "left", where, 0),
                   right = numberField(b, "right", where, 0);
      const double top = numberField(b, "top", where, 0),
                   bottom = numberField(b, "bottom", where, 0);
      gapX = int(std::lround((left + right) / (widthMm / w)));
      gapY = int(std::lround((top + bottom) / (heightMm / h)));
    }
    if (w <= 0 || h <= 0 || columns <= 0 || rows <= 0 || gapX < 0 || gapY < 0 ||
        gapX > kMaxDisplaySide || gapY > kMaxDisplaySide)
      throw FormatError(source, "display size and grid must be positive, bezels not negative");
    if ((long long)columns * rows > kMaxDisplays)
      throw FormatError(source, std::to_string((long long)columns * rows) + " displays, at most " +
                                    std::to_string(kMaxDisplays));
    wall = gridWall(id, w, h, columns, rows, gapX, gapY);
  }
  if (doc.contains("background")) wall.background = parseColor(doc["background"], source);
  return wall;
}

}  // namespace

long long Wall::displayPixels() const {
  long long n = 0;
  for (const auto& d : displays) n += d.rect.area();
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
    for (std::size_t k = 0; k < i; ++k) {
      const auto& o = wall.displays[k].rect;
      if (r.x < o.x + o.width && o.x < r.x + r.width && r.y < o.y + o.height &&
          o.y < r.y + r.height)
        throw FormatError(source, what + " overlaps display '" + wall.displays[k].name + "'");
    }
  }
}

Wall parseWall(const std::string& text, const std::string& source) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    throw FormatError(source, std::string("not valid JSON: ") + e.what());
  }
  if (!doc.is_object()) throw FormatError(source, "a wall file is a JSON object");
  Wall wall = doc.contains("surfaces") ? parseTide(doc, source) : parseVoxwall(doc, source);
  validateWall(wall, source);
  return wall;
}

Wall loadWall(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw FormatError(path, "cannot open wall file");
  std::stringstream text;
  text << in.rdbuf();
  return parseWall(text.str(), path);
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
