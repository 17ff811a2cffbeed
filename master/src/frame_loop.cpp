#include <chrono>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <voxwall/codec/errors.hpp>
#include <voxwall/master/frame_loop.hpp>

namespace voxwall::master {

std::vector<node::Rect> gridTiles(int width, int height, int tilesX, int tilesY) {
  if (tilesX < 1 || tilesY < 1 || tilesX > width || tilesY > height)
    throw std::invalid_argument("tile grid " + std::to_string(tilesX) + "x" +
                                std::to_string(tilesY) + " does not fit a " +
                                std::to_string(width) + "x" + std::to_string(height) + " screen");
  std::vector<node::Rect> tiles;
  for (int j = 0; j < tilesY; ++j)
    for (int i = 0; i < tilesX; ++i) {
      const int x0 = int((long long)width * i / tilesX),
                x1 = int((long long)width * (i + 1) / tilesX);
      const int y0 = int((long long)height * j / tilesY),
                y1 = int((long long)height * (j + 1) / tilesY);
      tiles.push_back({x0, y0, x1 - x0, y1 - y0});
    }
  return tiles;
}

FrameReport renderFrame(node::Backend& backend, const node::RenderVolume& volume,
                        const node::TransferFunction& tf, const node::RenderSettings& render,
                        const SequenceSettings& seq, int frame, node::Image& image) {
  node::Orbit orbit = seq.orbit;
  orbit.azimuthDeg += seq.orbitStepDeg * frame;
  const node::Camera camera = node::orbitCamera(orbit, node::boundingRadius(volume.info()));
  const node::FramePlan plan = node::planFrame(volume, camera, seq.width, seq.height, tf, render);
  image = node::Image(seq.width, seq.height);
  FrameReport report;
  report.frame = frame;
  node::Image tileImage;
  for (const auto& tile : gridTiles(seq.width, seq.height, seq.tilesX, seq.tilesY)) {
    const auto stats = backend.render(volume, plan, tile, tileImage);
    report.renderSeconds += stats.seconds;
    report.samples += stats.samples;
    image.paste(tileImage, tile);
  }
  return report;
}

void renderSequence(node::Backend& backend, const node::RenderVolume& volume,
                    const node::TransferFunction& tf, const node::RenderSettings& render,
                    const SequenceSettings& seq,
                    const std::function<void(const FrameReport&)>& onFrame) {
  if (seq.frames < 1) throw std::invalid_argument("--frames must be at least 1");
  if (!seq.outDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(seq.outDir, ec);
    if (ec) throw FormatError(seq.outDir, "cannot create output directory: " + ec.message());
  }
  node::Image image;
  for (int f = 0; f < seq.frames; ++f) {
    FrameReport report = renderFrame(backend, volume, tf, render, seq, f, image);
    if (!seq.outDir.empty()) {
      char name[64];
      std::snprintf(name, sizeof name, "frame_%05d.%s", f, seq.format.c_str());
      report.path = (std::filesystem::path(seq.outDir) / name).string();
      const auto start = std::chrono::steady_clock::now();
      node::writeImage(image, report.path, seq.background);
      report.writeSeconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    if (onFrame) onFrame(report);
  }
}

}  // namespace voxwall::master
