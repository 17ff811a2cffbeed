// Writes seeds for config_files_fuzz into the folder given: each is a reader byte (0xf0 and
// above: a camera command; else even: walls, 1 mod 4: colour map without a name, 3 mod 4: the
// map named "Cool to Warm") and a file.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_config_seeds DIR\n");
    return 2;
  }
  std::filesystem::create_directories(argv[1]);
  const std::pair<char, const char*> seeds[] = {
      {char(0xf0), "rotate 10 -5"},
      {char(0xf0), "zoom 1.5"},
      {char(0xf1), "pan\t0.25 -1e-3"},
      {char(0xf2), "reset"},
      {0, R"({"wall": "w", "display": {"width": 40, "height": 30, "width_mm": 400,
              "height_mm": 300}, "bezel_mm": {"left": 2, "right": 2}, "grid": {"columns": 2,
              "rows": 2}, "background": "#102030"})"},
      {0, R"({"wall": "lab", "size": [300, 100], "overlap": true, "displays": [
              {"name": "a", "x": 0, "y": 0, "width": 160, "height": 100},
              {"name": "b", "x": 140, "y": 0, "width": 160, "height": 100}]})"},
      {0, R"({"background": {"color": "#000000"}, "surfaces": [
              {"displayWidth": 192, "displayHeight": 108, "displaysPerScreenX": 2,
               "screenCountX": 2, "screenCountY": 3, "bezelWidth": 14, "bezelHeight": 12},
              {"displayWidth": 64, "displayHeight": 32, "screenCountX": 3, "bezelWidth": -8}]})"},
      {0, R"(<?xml version="1.0"?><configuration><dimensions numScreensX="2" numScreensY="1"
              displayWidth="64" displayHeight="48" bezelWidth="-4" displaysPerScreenX="2"/>
              <background color="#ff8000"/></configuration>)"},
      {0, R"(<configuration><dimensions numTilesWidth="3" screenWidth="50" screenHeight="40"
              mullionWidth="2"/></configuration>)"},
      {1, R"({"Name": "Lab", "ColorSpace": "Lab", "RGBPoints": [0, 0, 0, 1, 0.5, 1, 1, 0, 1, 1, 0,
              0], "Points": [0, 0, 0.5, 0, 1, 1, 0.3, 0.7]})"},
      {1, R"({"ColorSpace": "Wrapped HSV", "RGBPoints": [-3, 1, 0, 1, 40, 0.2, 0.9, 0.1]})"},
      {3, R"([{"Name": "Cool to Warm", "ColorSpace": "Diverging", "RGBPoints": [0, 0.23, 0.3,
              0.75, 1, 0.7, 0.015, 0.15]}, {"Name": "Step", "ColorSpace": "Step",
              "RGBPoints": [-1, 0, 0, 0, 1, 1, 1, 1], "Points": [-1, 0, 0.5, 0, 1, 1, 0.5, 0]}])"},
  };
  int n = 0;
  for (const auto& [reader, text] : seeds) {
    std::ofstream out(std::string(argv[1]) + "/seed" + std::to_string(n++), std::ios::binary);
    out.put(reader);
    out << text;
  }
  return 0;
}
