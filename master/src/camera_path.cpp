#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/master/camera_path.hpp>

namespace voxwall::master {

CameraPath CameraPath::orbit(const node::Orbit& start, double stepDeg) {
  CameraPath p;
  p.kind_ = Kind::Orbit;
  p.start_ = start;
  p.stepDeg_ = stepDeg;
  return p;
}

CameraPath CameraPath::orbitThenZoom(const node::Orbit& start, int orbitFrames, int zoomFrames,
                                     double zoomDistance) {
  if (orbitFrames < 1 || zoomFrames < 0 || !(zoomDistance > 0))
    throw std::invalid_argument(
        "orbit-zoom path: needs at least one orbit frame and a positive "
        "zoom distance");
  CameraPath p;
  p.kind_ = Kind::OrbitZoom;
  p.start_ = start;
  p.orbitFrames_ = orbitFrames;
  p.zoomFrames_ = zoomFrames;
  p.zoomDistance_ = zoomDistance;
  return p;
}

CameraPath CameraPath::fromKeyFrames(std::vector<KeyFrame> keys, const std::string& source) {
  if (keys.empty()) throw FormatError(source, "no key frames");
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto& o = keys[i].orbit;
    if (keys[i].frame < 0 || (i > 0 && keys[i].frame <= keys[i - 1].frame))
      throw FormatError(source, "key frame " + std::to_string(i) +
                                    ": frame numbers must be non-negative and increase");
    if (!std::isfinite(o.azimuthDeg) || !std::isfinite(o.elevationDeg) || !(o.distance > 0) ||
        !std::isfinite(o.distance) || !(o.fovYDeg > 0 && o.fovYDeg < 180) ||
        !std::isfinite(o.panX) || !std::isfinite(o.panY))
      throw FormatError(source, "key frame " + std::to_string(i) +
                                    ": needs finite angles, a positive distance and a field of "
                                    "view in (0, 180) degrees");
  }
  CameraPath p;
  p.kind_ = Kind::Keys;
  p.keys_ = std::move(keys);
  return p;
}

CameraPath CameraPath::fromJsonFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw FormatError(path, "cannot open camera path");
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(path, std::string("not valid JSON: ") + e.what());
  }
  if (!doc.is_object() || !doc.contains("keyframes") || !doc["keyframes"].is_array())
    throw FormatError(path, "expected an object with a \"keyframes\" array");
  std::vector<KeyFrame> keys;
  node::Orbit previous;
  for (const auto& k : doc["keyframes"]) {
    if (!k.is_object() || !k.contains("frame") || !k["frame"].is_number_integer())
      throw FormatError(
          path, "key frame " + std::to_string(keys.size()) + ": needs an integer \"frame\"");
    KeyFrame key;
    key.frame = k["frame"].get<int>();
    key.orbit = previous;
    auto read = [&](const char* name, double& value) {
      if (!k.contains(name)) return;
      if (!k[name].is_number())
        throw FormatError(path, "key frame " + std::to_string(keys.size()) + ": \"" + name +
                                    "\" is not a number");
      value = k[name].get<double>();
    };
    read("azimuth", key.orbit.azimuthDeg);
    read("elevation", key.orbit.elevationDeg);
    read("distance", key.orbit.distance);
    read("fov", key.orbit.fovYDeg);
    read("pan_x", key.orbit.panX);
    read("pan_y", key.orbit.panY);
    previous = key.orbit;
    keys.push_back(key);
  }
  return fromKeyFrames(std::move(keys), path);
}

node::Orbit CameraPath::at(int frame) const {
  switch (kind_) {
    case Kind::Orbit: {
      node::Orbit o = start_;
      o.azimuthDeg += stepDeg_ * frame;
      return o;
    }
    case Kind::OrbitZoom: {
      node::Orbit o = start_;
      if (frame < orbitFrames_) {
        o.azimuthDeg += 360.0 * frame / orbitFrames_;
        return o;
      }
      const double t =
          zoomFrames_ > 0 ? std::min(1.0, double(frame - orbitFrames_ + 1) / zoomFrames_) : 1.0;
      o.distance = start_.distance + (zoomDistance_ - start_.distance) * t;
      return o;
    }
    case Kind::Keys:
      break;
  }
  if (frame <= keys_.front().frame) return keys_.front().orbit;
  if (frame >= keys_.back().frame) return keys_.back().orbit;
  std::size_t i = 1;
  while (keys_[i].frame < frame) ++i;
  const auto& a = keys_[i - 1];
  const auto& b = keys_[i];
  const double t = double(frame - a.frame) / double(b.frame - a.frame);
  auto mix = [t](double x, double y) { return x + (y - x) * t; };
  node::Orbit o;
  o.azimuthDeg = mix(a.orbit.azimuthDeg, b.orbit.azimuthDeg);
  o.elevationDeg = mix(a.orbit.elevationDeg, b.orbit.elevationDeg);
  o.distance = mix(a.orbit.distance, b.orbit.distance);
  o.fovYDeg = mix(a.orbit.fovYDeg, b.orbit.fovYDeg);
  o.panX = mix(a.orbit.panX, b.orbit.panX);
  o.panY = mix(a.orbit.panY, b.orbit.panY);
  return o;
}

}  // namespace voxwall::master
