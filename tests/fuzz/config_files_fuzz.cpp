// libFuzzer target for the configuration files a user hands voxwall: wall files (voxwall JSON,
// Tide JSON with every surface, Tide XML) and ParaView colour-map files (one preset, lists,
// FILE:NAME picks). The first byte picks the reader. A FormatError is the expected answer to a bad
// file; anything else (another exception, a crash, a hang, a sanitizer report) is a bug. What a
// reader accepts must hold together: walls validate, maps evaluate to colours in [0, 1].
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <voxwall/core/errors.hpp>
#include <voxwall/node/transfer_function.hpp>
#include <voxwall/walls/wall.hpp>

using namespace voxwall;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    if (data[0] % 2 == 0) {
      for (const auto& wall : walls::parseWalls(text, "fuzz")) {
        walls::validateWall(wall, "fuzz");  // what the reader returns is a valid wall
        if (wall.displayPixels() <= 0 || wall.displayPixels() > (long long)wall.width * wall.height)
          std::abort();
      }
    } else {
      const std::string name = data[0] % 4 == 1 ? "" : "Cool to Warm";
      auto tf = node::TransferFunction::fromParaViewJsonText(text, "fuzz", name);
      tf.placeOnData(0.0, 255.0, std::nullopt);
      for (double x = -10; x <= 265; x += 5) {
        double rgba[4];
        tf.evaluate(x, rgba);
        for (const double v : rgba)
          if (!(v >= 0.0 && v <= 1.0)) std::abort();
      }
    }
  } catch (const FormatError&) {
  }
  return 0;
}
