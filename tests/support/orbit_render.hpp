// The render the codec render tests compare: a 3/4 orbit view (azimuth 35, elevation 25) of the
// whole volume on the CPU backend, optionally as tiles pasted into one image.
#pragma once

#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/core/rect.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::test {

voxwall::Image renderOrbit(const node::RenderVolume& volume, int w, int h,
                           const node::TransferFunction& tf, bool shading, int threads = 2,
                           const std::vector<voxwall::Rect>& tiles = {});
// The same with any render settings (level of detail, nearest sampling, ...).
voxwall::Image renderOrbit(const node::RenderVolume& volume, int w, int h,
                           const node::TransferFunction& tf, const node::RenderSettings& s,
                           int threads = 2, const std::vector<voxwall::Rect>& tiles = {});

}  // namespace voxwall::test
