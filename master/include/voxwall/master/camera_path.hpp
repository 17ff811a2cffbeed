// Where the camera is in every frame of a job: an orbit, an orbit followed by a zoom (the
// evaluation path of the SVMM thesis, Faas 2016, ch. 5), or key frames from a JSON file.
#pragma once

#include <string>
#include <vector>
#include <voxwall/node/camera.hpp>

namespace voxwall::master {

struct KeyFrame {
  int frame = 0;
  node::Orbit orbit;
};

class CameraPath {
 public:
  // Azimuth grows by `stepDeg` per frame from `start`.
  static CameraPath orbit(const node::Orbit& start, double stepDeg);
  // One full turn in `orbitFrames` frames, then the distance goes linearly from start.distance
  // to `zoomDistance` over the next `zoomFrames` frames (and stays there).
  static CameraPath orbitThenZoom(const node::Orbit& start, int orbitFrames, int zoomFrames,
                                  double zoomDistance);
  // Key frames, linearly interpolated in azimuth, elevation, distance, field of view and pan
  // (pan_x, pan_y in bounding radii); before
  // the first and after the last key the camera holds still. The file:
  //   {"keyframes": [{"frame": 0, "azimuth": 30, "elevation": 20, "distance": 2.6, "fov": 30},
  //                  {"frame": 50, "azimuth": 120, ...}]}
  // Missing fields take the previous key's value (the first key's take the defaults of Orbit).
  // Frames must increase strictly. Throws FormatError("<path>: ...").
  static CameraPath fromJsonFile(const std::string& path);
  static CameraPath fromKeyFrames(std::vector<KeyFrame> keys, const std::string& source);

  node::Orbit at(int frame) const;
  const std::vector<KeyFrame>& keys() const { return keys_; }

 private:
  enum class Kind { Orbit, OrbitZoom, Keys } kind_ = Kind::Orbit;
  node::Orbit start_;
  double stepDeg_ = 0;
  int orbitFrames_ = 1, zoomFrames_ = 0;
  double zoomDistance_ = 0;
  std::vector<KeyFrame> keys_;
};

}  // namespace voxwall::master
