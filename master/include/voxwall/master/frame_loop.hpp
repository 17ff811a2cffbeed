// The frame loop of a batch render (single rank for now): one camera per frame on an orbit,
// the screen rendered as one tile or cut into tiles, frames written as image files.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/node/renderer.hpp>

namespace voxwall::master {

struct SequenceSettings {
  int width = 1920, height = 1080;
  int frames = 1;
  node::Orbit orbit;           // camera of frame 0
  double orbitStepDeg = 5.0;   // azimuth added per frame
  int tilesX = 1, tilesY = 1;  // the screen cut into a grid of tiles (the same pixels either way)
  std::string outDir;          // empty: render without writing
  std::string format = "png";  // file extension for frames: png or exr
  std::optional<glm::dvec3> background;  // none: transparent, straight alpha in files
};

struct FrameReport {
  int frame = 0;
  double renderSeconds = 0, writeSeconds = 0;
  std::uint64_t samples = 0;
  std::string path;  // written file, empty when not writing
};

// Grid of tiles covering a width x height screen exactly (rows and columns differ by at most
// one pixel). Throws std::invalid_argument for counts < 1 or larger than the screen.
std::vector<node::Rect> gridTiles(int width, int height, int tilesX, int tilesY);

// Renders one frame of the sequence into `image` (screen size).
FrameReport renderFrame(node::Backend& backend, const node::RenderVolume& volume,
                        const node::TransferFunction& tf, const node::RenderSettings& render,
                        const SequenceSettings& seq, int frame, node::Image& image);

// Renders every frame and writes it (atomically) to outDir/frame_NNNNN.<format>; calls
// `onFrame` after each. Creates outDir. Throws FormatError on write errors.
void renderSequence(node::Backend& backend, const node::RenderVolume& volume,
                    const node::TransferFunction& tf, const node::RenderSettings& render,
                    const SequenceSettings& seq,
                    const std::function<void(const FrameReport&)>& onFrame = {});

}  // namespace voxwall::master
