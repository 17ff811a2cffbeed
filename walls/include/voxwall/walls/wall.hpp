// Display walls: the displays of a wall as rectangles of one virtual screen that includes the
// bezel gaps, so the renderer renders one picture and a line crosses a bezel straight; the sink
// crops each display's rectangle out of it.
//
// voxwall's wall file (JSON), a grid:
//   {"wall": "bigeye",
//    "display": {"width": 1920, "height": 1080, "width_mm": 1209.6, "height_mm": 680.4},
//    "bezel_mm": {"left": 1.75, "right": 1.75, "top": 1.75, "bottom": 1.75},
//    "grid": {"columns": 3, "rows": 4},
//    "background": [0, 0, 0]}
// The gap between neighbours is the two facing bezels in pixels of the display's pitch; instead
// of "bezel_mm" a file may give "bezel_px": {"x": 6, "y": 6} (the gaps themselves). Or explicit
// displays: {"wall": "lab", "size": [4000, 1200],
//            "displays": [{"name": "left", "x": 0, "y": 0, "width": 1920, "height": 1200}, ...]}
// Tide's configuration (BlueBrain/Tide) is read too: the first of its "surfaces", with
// displayWidth/displayHeight, screenCountX/screenCountY and bezelWidth/bezelHeight (pixels).
#pragma once

#include <glm/vec3.hpp>
#include <string>
#include <vector>
#include <voxwall/core/rect.hpp>

namespace voxwall::walls {

// Limits a wall file cannot exceed (a typo, not a wall).
inline constexpr int kMaxDisplays = 1024;
inline constexpr int kMaxDisplaySide = 16384;
inline constexpr int kMaxScreenSide = 65536;
inline constexpr long long kMaxScreenPixels = 1ll << 30;

struct Display {
  std::string name;
  voxwall::Rect rect;  // in virtual-screen pixels
};

struct Wall {
  std::string id;
  int width = 0, height = 0;  // the virtual screen, bezel gaps included
  std::vector<Display> displays;
  glm::dvec3 background{0.0};  // what JPEG tiles are composited onto, [0, 1]
  long long displayPixels() const;
};

// Reads a voxwall or Tide wall file. Throws FormatError("<path>: ...") naming what is wrong.
Wall loadWall(const std::string& path);
// The same from text (`source` names it in errors).
Wall parseWall(const std::string& json, const std::string& source);
// Checks sizes, limits, that displays lie on the screen and do not overlap, unique names.
// Throws FormatError(source, ...).
void validateWall(const Wall& wall, const std::string& source);
// One display covering a width x height screen (no wall file).
Wall singleDisplayWall(int width, int height);

}  // namespace voxwall::walls
