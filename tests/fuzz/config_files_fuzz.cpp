// libFuzzer target for the text a user hands voxwall: wall files (voxwall JSON, Tide JSON with
// every surface, Tide XML), ParaView colour-map files (one preset, lists, FILE:NAME picks) and
// camera commands (the sink's stdin and the pages' WebSockets). The first byte picks the reader
// (0xf0 and above: commands). A FormatError (for commands std::invalid_argument) is the expected
// answer to bad text; anything else (another exception, a crash, a hang, a sanitizer report) is a
// bug. What a reader accepts must hold together: walls validate, maps evaluate to colours in
// [0, 1], commands carry finite numbers within +-1e6 and zoom factors above 0.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <voxwall/core/errors.hpp>
#include <voxwall/node/transfer_function.hpp>
#include <voxwall/walls/sink.hpp>
#include <voxwall/walls/wall.hpp>

using namespace voxwall;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] >= 0xf0) {
    try {
      const net::Control c = walls::parseControlLine(text);
      for (const double v : {c.a, c.b})
        if (!std::isfinite(v) || std::abs(v) > 1e6) std::abort();
      if (c.command == net::ControlCommand::Zoom && !(c.a > 0)) std::abort();
    } catch (const std::invalid_argument&) {
    }
    return 0;
  }
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
