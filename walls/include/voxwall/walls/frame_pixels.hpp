// The pixels of an assembled frame, decoded only where something needs pixels: the files the sink
// writes (one display at a time, or the whole screen) and the overview page (the whole screen
// scaled down, with the JPEG decoder's own DCT scaling). The displays' pages get the segments as
// they arrived and decode them themselves.
#pragma once

#include <cstdint>
#include <voxwall/core/image.hpp>
#include <voxwall/core/rect.hpp>
#include <voxwall/walls/frame_assembler.hpp>

namespace voxwall::walls {

// The opaque RGBA8 pixel of a wall's background colour ([0, 1] per channel).
std::uint32_t backgroundPixel(const glm::dvec3& background);

// Decodes the segments of `frame` that touch `region` (virtual-screen pixels) into an opaque
// image of ceil(region.width / scale) x ceil(region.height / scale) pixels: pixel (x, y) shows the
// virtual-screen point at the centre of its scale x scale block. At scale 1 this is exactly what
// the ranks sent (an interactive frame's pixels repeated over their step x step blocks); at
// scale > 1 JPEG segments are decoded at 1/2, 1/4 or 1/8 by the decoder where that fits, and the
// rest is taken by nearest neighbour. Pixels no segment covers get `fill`. Where segments
// overlap, the later one wins. Segments are decoded on `threads` threads (0: all cores).
// Throws FormatError when a segment does not decode (a corrupt body behind a good header).
voxwall::Image decodeRegion(const AssembledFrame& frame, const voxwall::Rect& region, int scale,
                            std::uint32_t fill, int threads = 0);

}  // namespace voxwall::walls
