// Cameras, the virtual screen and tiles of it.
#pragma once

#include <glm/vec3.hpp>

namespace voxwall::node {

// A rectangle of the virtual screen in pixels; row 0 at the top.
struct Rect {
  int x = 0, y = 0, width = 0, height = 0;
  long long area() const { return (long long)width * height; }
  // Whether the rectangle is non-empty and lies inside a screenWidth x screenHeight screen.
  // Computed in 64 bits: a rectangle from a file or the wire cannot overflow its way inside.
  bool fitsIn(int screenWidth, int screenHeight) const {
    return x >= 0 && y >= 0 && width > 0 && height > 0 && (long long)x + width <= screenWidth &&
           (long long)y + height <= screenHeight;
  }
  bool operator==(const Rect&) const = default;
};

// A perspective pinhole camera in world space (millimetres for medical data).
struct Camera {
  glm::dvec3 eye{0, -3, 0};
  glm::dvec3 center{0, 0, 0};
  glm::dvec3 up{0, 0, 1};
  double fovYDeg = 30.0;  // full vertical field of view of the whole virtual screen
};

// An orbit around the volume's centre: azimuth around +z from +x, elevation above the xy plane,
// distance in multiples of the volume's bounding-sphere radius.
struct Orbit {
  double azimuthDeg = 30.0;
  double elevationDeg = 20.0;
  double distance = 2.6;
  double fovYDeg = 30.0;
  // Moves eye and centre together across the view (along the screen's right and up), in
  // bounding radii: the volume slides the other way on the screen.
  double panX = 0.0, panY = 0.0;
};
Camera orbitCamera(const Orbit& orbit, double boundingRadius);

// The off-axis view frustum of one tile of a `screenWidth` x `screenHeight` virtual screen, at
// near distance `nearDist` (OpenGL glFrustum convention): rendering the tile with it gives exactly
// the tile's pixels of the full render. Throws std::invalid_argument for an empty tile.
struct Frustum {
  double left, right, bottom, top, nearDist, farDist;
};
Frustum tileFrustum(const Camera& camera, int screenWidth, int screenHeight, const Rect& tile,
                    double nearDist, double farDist);

}  // namespace voxwall::node
