// Cameras, the virtual screen and tiles of it.
#pragma once

#include <glm/vec3.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <voxwall/core/rect.hpp>

namespace voxwall::node {

// A perspective pinhole camera in world space (millimetres for medical data).
struct Camera {
  glm::dvec3 eye{0, -3, 0};
  glm::dvec3 center{0, 0, 0};
  glm::dvec3 up{0, 0, 1};
  double fovYDeg = 30.0;  // full vertical field of view of the whole virtual screen
};

// An orbit around the volume's centre: azimuth around +z from +x, elevation above the xy plane,
// distance in multiples of the volume's bounding-sphere radius. World axes are the patient's
// (LPS: +x left, +y posterior, +z superior; the renderer maps them onto the volume's grid through
// its orientation), so azimuth 0 looks at the patient's left side and -90 at the face.
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

// The orbit angles of a named anatomical view, from where the viewer stands: "anterior"
// (azimuth -90: facing the patient, whose left is on the picture's right), "posterior", "left",
// "right", "superior" (from above, anterior up), "inferior" (from the feet, anterior up, the
// patient's left on the right, as axial slices are read); nullopt for any other name.
struct ViewAngles {
  double azimuthDeg, elevationDeg;
};
std::optional<ViewAngles> anatomicalView(std::string_view name);
std::string anatomicalViewNames();  // "anterior, posterior, left, right, superior, inferior"

// The off-axis view frustum of one tile of a `screenWidth` x `screenHeight` virtual screen, at
// near distance `nearDist` (OpenGL glFrustum convention): rendering the tile with it gives exactly
// the tile's pixels of the full render. Throws std::invalid_argument for an empty tile.
struct Frustum {
  double left, right, bottom, top, nearDist, farDist;
};
Frustum tileFrustum(const Camera& camera, int screenWidth, int screenHeight, const Rect& tile,
                    double nearDist, double farDist);

}  // namespace voxwall::node
