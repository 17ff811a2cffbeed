#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <voxwall/core/errors.hpp>
#include <voxwall/node/transfer_function.hpp>

namespace voxwall::node {
namespace {

struct Preset {
  const char* name;
  std::vector<ColorPoint> colors;
  std::vector<OpacityPoint> opacities;
  ColorSpace space = ColorSpace::Rgb;
  bool hounsfield = false;  // points in Hounsfield units, applied as they are
};

const std::vector<Preset>& presets() {
  static const std::vector<Preset> kPresets = {
      // Grey, transparent below 30% of the range: brain-extracted MRI and similar.
      {"mri", {{0, 0, 0, 0}, {1, 1, 1, 1}}, {{0, 0}, {0.3, 0}, {1, 0.8}}},
      {"grey", {{0, 0, 0, 0}, {1, 1, 1, 1}}, {{0, 0}, {1, 1}}},
      // Bone above ~45% of a CT range, soft tissue faint.
      {"ct-bone",
       {{0, 0, 0, 0}, {0.3, 0.55, 0.25, 0.15}, {0.5, 0.88, 0.6, 0.29}, {1, 1, 0.94, 0.95}},
       {{0, 0}, {0.45, 0}, {0.6, 0.6}, {1, 0.9}}},
      {"ct-soft",
       {{0, 0, 0, 0}, {0.35, 0.73, 0.25, 0.30}, {0.55, 0.9, 0.82, 0.56}, {1, 1, 1, 1}},
       {{0, 0}, {0.3, 0}, {0.4, 0.15}, {0.6, 0.3}, {1, 0.8}}},
      {"hot", {{0, 0, 0, 0}, {0.4, 0.9, 0, 0}, {0.8, 1, 0.9, 0}, {1, 1, 1, 1}}, {{0, 0}, {1, 1}}},
      // Moreland's cool-warm end points (ParaView's "Cool to Warm"), diverging through Msh.
      {"cool-warm",
       {{0, 0.231373, 0.298039, 0.752941}, {1, 0.705882, 0.0156863, 0.14902}},
       {{0, 0}, {1, 0.5}},
       ColorSpace::Diverging},
      // On Hounsfield units (CT), whatever the data's range: air -1000, lung -900..-500, fat
      // -100..-50, water 0, soft tissue 20..80, contrast-filled vessels 150..500, cancellous bone
      // 300..700, cortical bone 700..1900.
      {"hu-bone",
       {{-1000, 0, 0, 0}, {150, 0.55, 0.25, 0.15}, {400, 0.88, 0.6, 0.29}, {1500, 1, 0.94, 0.95}},
       {{-1000, 0}, {150, 0}, {300, 0.35}, {700, 0.7}, {1500, 0.9}, {3071, 0.9}},
       ColorSpace::Rgb,
       true},
      {"hu-soft-tissue",
       {{-1000, 0, 0, 0},
        {-100, 0.9, 0.8, 0.45},
        {40, 0.73, 0.25, 0.30},
        {300, 0.95, 0.9, 0.8},
        {1000, 1, 1, 1}},
       {{-1000, 0}, {-200, 0}, {-100, 0.05}, {40, 0.2}, {80, 0.3}, {300, 0.6}, {3071, 0.8}},
       ColorSpace::Rgb,
       true},
      {"hu-lung",
       {{-1000, 0, 0, 0}, {-900, 0.75, 0.45, 0.45}, {-500, 0.95, 0.75, 0.7}, {0, 1, 0.9, 0.85}},
       {{-1000, 0}, {-950, 0}, {-850, 0.04}, {-500, 0.25}, {-300, 0}, {3071, 0}},
       ColorSpace::Rgb,
       true},
      {"hu-angio",
       {{-1000, 0, 0, 0}, {100, 0.6, 0.05, 0.05}, {300, 0.95, 0.2, 0.15}, {700, 1, 0.95, 0.9}},
       {{-1000, 0}, {100, 0}, {180, 0.5}, {450, 0.8}, {700, 0.2}, {3071, 0.3}},
       ColorSpace::Rgb,
       true},
      {"hu-skin",
       {{-1000, 0, 0, 0}, {-500, 0.8, 0.55, 0.45}, {0, 0.95, 0.75, 0.62}, {3071, 1, 0.9, 0.8}},
       {{-1000, 0}, {-500, 0}, {-300, 0.6}, {-100, 0.95}, {3071, 0.95}},
       ColorSpace::Rgb,
       true},
  };
  return kPresets;
}

// One segment of ParaView's/VTK's piecewise function between v1 and v2 at t in [0, 1].
double opacitySegment(double v1, double v2, double t, double midpoint, double sharpness) {
  midpoint = std::clamp(midpoint, 1e-5, 1.0 - 1e-5);
  t = t < midpoint ? 0.5 * t / midpoint : 0.5 + 0.5 * (t - midpoint) / (1.0 - midpoint);
  if (sharpness > 0.99) return t < 0.5 ? v1 : v2;
  if (sharpness < 0.01) return v1 + t * (v2 - v1);
  // Squeeze t towards the midpoint, then a Hermite curve whose end slopes shrink as sharpness
  // grows (the shape ParaView's opacity editor draws).
  if (t < 0.5)
    t = 0.5 * std::pow(t * 2.0, 1.0 + 10.0 * sharpness);
  else if (t > 0.5)
    t = 1.0 - 0.5 * std::pow((1.0 - t) * 2.0, 1.0 + 10.0 * sharpness);
  const double t2 = t * t, t3 = t2 * t;
  const double h1 = 2 * t3 - 3 * t2 + 1, h2 = -2 * t3 + 3 * t2, h3 = t3 - 2 * t2 + t, h4 = t3 - t2;
  const double slope = (1.0 - sharpness) * (v2 - v1);
  const double v = h1 * v1 + h2 * v2 + h3 * slope + h4 * slope;
  return std::clamp(v, std::min(v1, v2), std::max(v1, v2));
}

[[noreturn]] void bad(const std::string& source, const std::string& what) {
  throw FormatError(source, what);
}

std::vector<double> numbers(const nlohmann::json& j, const char* key, std::size_t group,
                            const std::string& source) {
  const auto& a = j.at(key);
  if (!a.is_array()) bad(source, std::string("'") + key + "' is not an array");
  if (a.empty() || a.size() % group)
    bad(source, std::string("'") + key + "' must hold groups of " + std::to_string(group) +
                    " numbers, has " + std::to_string(a.size()));
  std::vector<double> out;
  for (auto& v : a) {
    if (!v.is_number()) bad(source, std::string("'") + key + "' holds a non-number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) bad(source, std::string("'") + key + "' holds a non-finite number");
    out.push_back(d);
  }
  for (std::size_t i = group; i < out.size(); i += group)
    if (out[i] < out[i - group])
      bad(source, std::string("'") + key + "' positions are not in increasing order");
  return out;
}

}  // namespace

std::vector<std::string> TransferFunction::presetNames() {
  std::vector<std::string> names;
  for (auto& p : presets()) names.emplace_back(p.name);
  return names;
}

TransferFunction TransferFunction::preset(const std::string& name) {
  for (auto& p : presets())
    if (name == p.name) {
      TransferFunction tf;
      tf.name = p.name;
      tf.colors = p.colors;
      tf.opacities = p.opacities;
      tf.colorSpace = p.space;
      tf.normalized = !p.hounsfield;
      tf.hounsfield = p.hounsfield;
      return tf;
    }
  std::string list;
  for (auto& n : presetNames()) list += (list.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown transfer-function preset '" + name + "' (built-in: " + list +
                              "; or a ParaView .json file)");
}

namespace {

std::string readText(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw FormatError(path, "cannot open transfer-function file");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

nlohmann::json parseJson(const std::string& text, const std::string& source) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // also out_of_range: a number too large
    bad(source, std::string("not valid JSON: ") + e.what());
  }
}

// The colour maps of a preset file: objects with "RGBPoints" (a list may hold opacity-only or
// other entries, which are not colour maps).
std::vector<const nlohmann::json*> colorMaps(const nlohmann::json& doc) {
  std::vector<const nlohmann::json*> maps;
  if (doc.is_array()) {
    for (auto& p : doc)
      if (p.is_object() && p.contains("RGBPoints")) maps.push_back(&p);
  } else if (doc.is_object() && doc.contains("RGBPoints")) {
    maps.push_back(&doc);
  }
  return maps;
}

std::string nameOf(const nlohmann::json& preset, std::size_t index) {
  if (preset.contains("Name") && preset["Name"].is_string())
    return preset["Name"].get<std::string>();
  return "#" + std::to_string(index);
}

std::string joinNames(const std::vector<std::string>& names) {
  std::string list;
  for (auto& n : names) list += (list.empty() ? "'" : ", '") + n + "'";
  return list;
}

// Exactly [0, 1] or [-1, 1]: how ParaView's bundled presets are written.
bool spansUnitRange(double lo, double hi) {
  return (lo == 0.0 && hi == 1.0) || (lo == -1.0 && hi == 1.0);
}

TransferFunction fromPreset(const nlohmann::json& preset, const std::string& source,
                            std::string name) {
  TransferFunction tf;
  tf.name = std::move(name);
  const auto rgb = numbers(preset, "RGBPoints", 4, source);
  for (std::size_t i = 0; i < rgb.size(); i += 4) {
    for (int c = 1; c <= 3; ++c)
      if (rgb[i + c] < 0 || rgb[i + c] > 1) bad(source, "'RGBPoints' colours must be in [0, 1]");
    tf.colors.push_back({rgb[i], rgb[i + 1], rgb[i + 2], rgb[i + 3]});
  }
  if (preset.contains("Points")) {
    const auto pts = numbers(preset, "Points", 4, source);
    for (std::size_t i = 0; i < pts.size(); i += 4) {
      if (pts[i + 1] < 0 || pts[i + 1] > 1) bad(source, "'Points' opacities must be in [0, 1]");
      tf.opacities.push_back({pts[i], pts[i + 1], pts[i + 2], pts[i + 3]});
    }
  }
  tf.normalized = spansUnitRange(tf.domainMin(), tf.domainMax());
  if (tf.opacities.empty()) {
    const double lo = tf.colors.front().x, hi = tf.colors.back().x;
    tf.ownOpacity = false;
    tf.opacities = {{lo, 0.0}, {lo + 0.3 * (hi - lo), 0.0}, {hi, 0.8}};
    tf.warnings.push_back(tf.noOpacityWarning());
  }
  if (preset.contains("ColorSpace")) {
    const std::string space =
        preset["ColorSpace"].is_string() ? preset["ColorSpace"].get<std::string>() : "";
    if (space == "Lab/CIEDE2000") {
      tf.colorSpace = ColorSpace::Lab;
      tf.warnings.push_back("colour space 'Lab/CIEDE2000' is interpolated in Lab");
    } else if (!colorSpaceFromName(space, &tf.colorSpace)) {
      tf.warnings.push_back("unknown colour space '" + space + "': interpolated in RGB");
    }
  }
  return tf;
}

}  // namespace

TransferFunction TransferFunction::fromParaViewJson(const std::string& path,
                                                    const std::string& name) {
  return fromParaViewJsonText(readText(path), path, name);
}

std::vector<std::string> TransferFunction::namesInParaViewJson(const std::string& path) {
  const auto doc = parseJson(readText(path), path);
  std::vector<std::string> names;
  const auto maps = colorMaps(doc);
  for (std::size_t i = 0; i < maps.size(); ++i) names.push_back(nameOf(*maps[i], i));
  return names;
}

TransferFunction TransferFunction::fromParaViewJsonText(const std::string& text,
                                                        const std::string& source,
                                                        const std::string& name) {
  const auto doc = parseJson(text, source);
  const auto maps = colorMaps(doc);
  if (maps.empty()) bad(source, "no ParaView preset with 'RGBPoints' found");
  std::vector<std::string> names;
  for (std::size_t i = 0; i < maps.size(); ++i) names.push_back(nameOf(*maps[i], i));
  if (name.empty()) {
    if (maps.size() > 1)
      bad(source, "holds " + std::to_string(maps.size()) + " colour maps (" + joinNames(names) +
                      "): pick one with --tf FILE:NAME");
    return fromPreset(*maps[0], source, names[0]);
  }
  for (std::size_t i = 0; i < maps.size(); ++i)
    if (names[i] == name) return fromPreset(*maps[i], source, names[i]);
  bad(source, "no colour map named '" + name + "' (it has " + joinNames(names) + ")");
}

TransferFunction::SpecParts TransferFunction::splitSpec(const std::string& spec) {
  namespace fs = std::filesystem;
  if (fs::exists(spec) || spec.ends_with(".json")) return {spec, ""};
  // FILE:NAME, split at the first ':' after which the file exists (names may hold ':').
  for (auto colon = spec.find(':'); colon != std::string::npos; colon = spec.find(':', colon + 1))
    if (fs::is_regular_file(spec.substr(0, colon)))
      return {spec.substr(0, colon), spec.substr(colon + 1)};
  return {"", spec};
}

TransferFunction TransferFunction::load(const std::string& spec) {
  const auto [file, name] = splitSpec(spec);
  return file.empty() ? preset(name) : fromParaViewJson(file, name);
}

void TransferFunction::takeOpacityFrom(const TransferFunction& other) {
  opacities = other.opacities;
  if (!ownOpacity)
    warnings.erase(std::remove(warnings.begin(), warnings.end(), noOpacityWarning()),
                   warnings.end());
  ownOpacity = other.ownOpacity;
}

std::string TransferFunction::noOpacityWarning() const {
  return "'" + name +
         "' has no opacity 'Points': transparent below 30% of its range, rising to 0.8 at the top "
         "(--opacity FILE|PRESET picks another curve)";
}

std::string TransferFunction::placeOnData(double dataLo, double dataHi,
                                          const std::optional<std::pair<double, double>>& range) {
  char line[512];
  if (range) {
    *this = rescaled(range->first, range->second);
    std::snprintf(line, sizeof line, "'%s' stretched over --tf-range %g..%g", name.c_str(),
                  range->first, range->second);
  } else if (normalized) {
    if (!(dataHi > dataLo)) dataHi = dataLo + 1.0;
    *this = rescaled(dataLo, dataHi);
    std::snprintf(line, sizeof line, "'%s' is normalized: stretched over the data range %g..%g",
                  name.c_str(), dataLo, dataHi);
  } else if (hounsfield) {
    std::snprintf(line, sizeof line, "'%s' is in Hounsfield units: applied as it is", name.c_str());
  } else {
    std::snprintf(line, sizeof line, "'%s' is in data values (%g..%g): applied as it is",
                  name.c_str(), domainMin(), domainMax());
  }
  return line;
}

double TransferFunction::domainMin() const {
  double lo = INFINITY;
  for (auto& c : colors) lo = std::min(lo, c.x);
  for (auto& o : opacities) lo = std::min(lo, o.x);
  return lo;
}

double TransferFunction::domainMax() const {
  double hi = -INFINITY;
  for (auto& c : colors) hi = std::max(hi, c.x);
  for (auto& o : opacities) hi = std::max(hi, o.x);
  return hi;
}

TransferFunction TransferFunction::rescaled(double lo, double hi) const {
  const double a = domainMin(), b = domainMax();
  const double scale = b > a ? (hi - lo) / (b - a) : 0.0;
  TransferFunction tf = *this;
  for (auto& c : tf.colors) c.x = lo + (c.x - a) * scale;
  for (auto& o : tf.opacities) o.x = lo + (o.x - a) * scale;
  return tf;
}

void TransferFunction::evaluate(double x, double rgba[4]) const {
  if (colors.empty()) {
    rgba[0] = rgba[1] = rgba[2] = 1.0;
  } else if (x <= colors.front().x) {
    rgba[0] = colors.front().r, rgba[1] = colors.front().g, rgba[2] = colors.front().b;
  } else if (x >= colors.back().x) {
    rgba[0] = colors.back().r, rgba[1] = colors.back().g, rgba[2] = colors.back().b;
  } else {
    auto it = std::upper_bound(colors.begin(), colors.end(), x,
                               [](double v, const ColorPoint& p) { return v < p.x; });
    const ColorPoint& b = *it;
    const ColorPoint& a = *(it - 1);
    const double t = b.x > a.x ? (x - a.x) / (b.x - a.x) : 1.0;
    const Rgb c = interpolateColor(colorSpace, {a.r, a.g, a.b}, {b.r, b.g, b.b}, t);
    rgba[0] = c[0], rgba[1] = c[1], rgba[2] = c[2];
  }
  if (opacities.empty()) {
    rgba[3] = 1.0;
  } else if (x <= opacities.front().x) {
    rgba[3] = opacities.front().opacity;
  } else if (x >= opacities.back().x) {
    rgba[3] = opacities.back().opacity;
  } else {
    auto it = std::upper_bound(opacities.begin(), opacities.end(), x,
                               [](double v, const OpacityPoint& p) { return v < p.x; });
    const OpacityPoint& b = *it;
    const OpacityPoint& a = *(it - 1);
    const double t = b.x > a.x ? (x - a.x) / (b.x - a.x) : 1.0;
    rgba[3] = opacitySegment(a.opacity, b.opacity, t, a.midpoint, a.sharpness);
  }
}

HostLut TransferFunction::bake(double lo, double hi, double stepVoxels, int entries,
                               bool preIntegrate) const {
  if (entries < 2) throw std::invalid_argument("a transfer-function table needs 2 or more entries");
  if (!(stepVoxels > 0)) throw std::invalid_argument("the ray step must be positive");
  if (!(hi > lo)) hi = lo + 1.0;
  HostLut lut;
  lut.lo = float(lo);
  lut.hi = float(hi);
  const auto n = std::size_t(entries);
  lut.entries.resize(n + 1);
  std::vector<glm::dvec4> point(n + 1);  // colour and per-step depth, in double for the integrals
  for (std::size_t i = 0; i < n; ++i) {
    double rgba[4];
    evaluate(lo + (hi - lo) * double(i) / double(n - 1), rgba);
    if (preIntegrate) {
      // An opacity of 1 would be an infinite depth: one in a million gets through instead.
      const double depth = -std::log(1.0 - std::min(rgba[3], 1.0 - 1e-6)) * stepVoxels;
      point[i] = glm::dvec4(rgba[0], rgba[1], rgba[2], rgba[3] > 0.0 ? depth : 0.0);
    } else {
      const double alpha = rgba[3] >= 1.0 ? 1.0 : 1.0 - std::pow(1.0 - rgba[3], stepVoxels);
      point[i] = glm::dvec4(rgba[0], rgba[1], rgba[2], alpha);
    }
    lut.entries[i] = glm::vec4(point[i]);
  }
  point[n] = point[n - 1];
  lut.entries[n] = lut.entries[n - 1];
  if (preIntegrate) {
    // Exact integrals of the linear interpolation between entries: depth is linear on an
    // interval, colour x depth quadratic.
    lut.integral.resize(n + 1);
    glm::dvec4 sum(0.0);
    for (std::size_t i = 0; i < n; ++i) {
      lut.integral[i] = glm::vec4(sum);
      const glm::dvec4 a = point[i], b = point[i + 1];
      const glm::dvec3 c0(a), dc = glm::dvec3(b) - c0;
      const double d0 = a.w, dd = b.w - a.w;
      sum += glm::dvec4(c0 * d0 + (c0 * dd + dc * d0) / 2.0 + dc * dd / 3.0, d0 + dd / 2.0);
    }
    lut.integral[n] = lut.integral[n - 1];
  }
  lut.buildRangeMax();
  return lut;
}

void HostLut::buildRangeMax() {
  rangeMax_.clear();
  std::vector<float> level(entries.size());  // (the guard entry repeats the last)
  for (std::size_t i = 0; i < entries.size(); ++i) level[i] = entries[i].a;
  rangeMax_.push_back(level);
  for (std::size_t width = 2; width <= entries.size(); width *= 2) {
    const auto& prev = rangeMax_.back();
    std::vector<float> next(entries.size() - width + 1);
    for (std::size_t i = 0; i < next.size(); ++i) next[i] = std::max(prev[i], prev[i + width / 2]);
    rangeMax_.push_back(std::move(next));
  }
}

float HostLut::maxOpacity(float a, float b) const {
  const auto lut = view();
  const float fa = std::clamp(lut.coordinate(std::min(a, b)), 0.0f, lut.last);
  const float fb = std::clamp(lut.coordinate(std::max(a, b)), 0.0f, lut.last);
  const auto i0 = std::size_t(std::floor(fa));
  const auto i1 = std::min(std::size_t(std::ceil(fb)), entries.size() - 1);
  if (rangeMax_.empty()) {
    float m = 0.0f;
    for (std::size_t i = i0; i <= i1; ++i) m = std::max(m, entries[i].a);
    return m;
  }
  // Two overlapping power-of-two windows cover [i0, i1].
  const std::size_t n = i1 - i0 + 1;
  std::size_t level = 0;
  while ((std::size_t(2) << level) <= n) ++level;
  const auto& row = rangeMax_[level];
  return std::max(row[i0], row[i1 + 1 - (std::size_t(1) << level)]);
}

}  // namespace voxwall::node
