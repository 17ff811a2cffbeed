// Fewer rays where the screen magnifies the volume: a tile's pixels from a lattice of rays that is
// refined where the picture changes.
//
// The lattice lives in virtual-screen pixels, aligned to the screen's origin: at stride S its
// points are the pixels whose coordinates are both multiples of S, and a cell is the S x S pixels
// [i S, (i + 1) S) x [j S, (j + 1) S) with its four corner points. Per cell, top-down:
//   1. the rays through its four corners are cast;
//   2. if any channel of those four 8-bit colours spans more than the refinement threshold
//      (RenderSettings::refineAboveLevels), the cell is split into four cells of half the stride
//      and each is treated the same way (the new corners are the old ones plus five midpoints);
//   3. else (or at stride 1) each of its pixels is the bilinear blend of its corners, in integers
//      (a corner pixel is its own ray).
// A pixel's value depends only on the cell tree above it, and a cell's split only on its corner
// rays, which are the same rays in any tile: so the picture is the same for any cut of the
// screen into tiles or bands and any thread count (a tile casts the corner rays of its border
// cells past its own edges). Across SIMD widths a corner may differ by rounding (a level) and so
// flip a split near the threshold; either way that cell's pixels stay within the threshold of
// its rays. A feature is found as long as it covers a lattice ray: the stride the frame picks
// (autoLatticeStride) is at most half a projected voxel.
#pragma once

#include <atomic>
#include <voxwall/core/image.hpp>
#include <voxwall/core/rect.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::node {

// Renders `tile` into `out` (resized to it) from the lattice at plan.latticeStride, its rays cast
// by backend.renderPoints; the stats count the rays cast. Stops as render() does.
TileStats renderLattice(Backend& backend, const RenderVolume& volume, const FramePlan& plan,
                        const Rect& tile, Image& out, CostGrid* costs,
                        const std::atomic<bool>* stop);

// The largest difference between the four RGBA8 colours in any channel (the refinement test).
int cornerSpread(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d);

// The bilinear blend of the corners of an s x s cell (c00 top left, c10 top right, c01 bottom
// left, c11 bottom right) at offset (fx, fy) in [0, s), per channel, rounded to nearest: integer
// arithmetic, so every machine gives the same value.
std::uint32_t blendCorners(std::uint32_t c00, std::uint32_t c10, std::uint32_t c01,
                           std::uint32_t c11, int s, int fx, int fy);

}  // namespace voxwall::node
