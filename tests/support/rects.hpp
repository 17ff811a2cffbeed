// Rectangle relations for tests of how screens are cut.
#pragma once

#include <voxwall/core/rect.hpp>

namespace voxwall::test {

inline bool inside(const voxwall::Rect& a, const voxwall::Rect& b) {
  return a.x >= b.x && a.y >= b.y && a.x + a.width <= b.x + b.width &&
         a.y + a.height <= b.y + b.height;
}

inline bool disjoint(const voxwall::Rect& a, const voxwall::Rect& b) {
  return a.x >= b.x + b.width || b.x >= a.x + a.width || a.y >= b.y + b.height ||
         b.y >= a.y + a.height;
}

}  // namespace voxwall::test
