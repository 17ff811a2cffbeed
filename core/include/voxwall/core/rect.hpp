// Rectangles of the virtual screen: what a tile, a display and a rank's share of a frame are.
#pragma once

namespace voxwall {

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
  // Whether the two share a pixel (64-bit: no overflow).
  bool overlaps(const Rect& o) const {
    return x < (long long)o.x + o.width && o.x < (long long)x + width &&
           y < (long long)o.y + o.height && o.y < (long long)y + height;
  }
  bool operator==(const Rect&) const = default;
};

}  // namespace voxwall
