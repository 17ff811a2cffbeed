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
// Displays that overlap are refused unless the file says "overlap": true (a typo is likelier than
// an edge-blended projector setup).
// Tide's configurations (BlueBrain/Tide) are read with Tide's geometry: every one of the JSON
// form's "surfaces" (displayWidth/Height, displaysPerScreenX/Y, screenCountX/Y, bezelWidth/Height
// in pixels, negative for overlapping displays, background.color), and the XML form's
// <dimensions> (one surface). docs/wall.md has the mapping.
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
  bool overlapping = false;    // displays may share pixels (negative bezels, "overlap": true)
  std::string description;     // how the file described it, for listings (may be empty)
  // Pixels of the virtual screen that some display shows (shared pixels counted once).
  long long displayPixels() const;
};

// Reads a voxwall or Tide wall file: every surface it describes (a voxwall file has one), each
// checked. Throws FormatError("<path>: ...") naming the field that is wrong.
std::vector<Wall> loadWalls(const std::string& path);
// The same from text (`source` names it in errors).
std::vector<Wall> parseWalls(const std::string& text, const std::string& source);
// One surface of the file (--surface, default 0); a missing one is a FormatError that says how
// many there are.
Wall loadWall(const std::string& path, int surface = 0);
Wall selectSurface(std::vector<Wall> walls, int surface, const std::string& source);
Wall parseWall(const std::string& text, const std::string& source, int surface = 0);
// "surface N: D display(s), virtual screen WxH - <description>": one line of a listing.
std::string describeSurface(const Wall& wall, int index);
// Checks sizes, limits, that displays lie on the screen and do not overlap (unless the wall says
// they may), unique names. Throws FormatError(source, ...).
void validateWall(const Wall& wall, const std::string& source);
// One display covering a width x height screen (no wall file).
Wall singleDisplayWall(int width, int height);

}  // namespace voxwall::walls
