#include <gtest/gtest.h>

#include <voxwall/core/errors.hpp>
#include <voxwall/walls/wall.hpp>

using namespace voxwall;

namespace {
const std::string kWalls = VOXWALL_WALLS_DIR;
}

TEST(Wall, ShippedWallsLoad) {
  const auto bigeye = walls::loadWall(kWalls + "/bigeye.json");
  EXPECT_EQ(bigeye.id, "bigeye");
  ASSERT_EQ(bigeye.displays.size(), 12u);
  EXPECT_EQ(bigeye.displayPixels(), 5760ll * 4320);
  // 1.75 mm bezels on each side at 0.63 mm per pixel: 6-pixel gaps.
  EXPECT_EQ(bigeye.width, 5760 + 2 * 6);
  EXPECT_EQ(bigeye.height, 4320 + 3 * 6);
  EXPECT_EQ(bigeye.displays[4].name, "r1c1");
  EXPECT_EQ(bigeye.displays[4].rect, (voxwall::Rect{1926, 1086, 1920, 1080}));
  const auto ci = walls::loadWall(kWalls + "/ci-2x2.json");
  EXPECT_EQ(ci.displays.size(), 4u);
  EXPECT_EQ(ci.width, 196);
  EXPECT_EQ(ci.height, 132);
  const auto desk = walls::loadWall(kWalls + "/desktop.json");
  EXPECT_EQ(desk.width, 1920);
  EXPECT_EQ(desk.displays.size(), 1u);
}

TEST(Wall, ReadsTideConfiguration) {
  const auto wall = walls::parseWall(R"({
    "master": {"display": ":0", "host": "localhost"},
    "processes": [],
    "surfaces": [{"background": {"color": "#ff8000"}, "displayWidth": 400, "displayHeight": 300,
                  "screenCountX": 3, "screenCountY": 2, "bezelWidth": 10, "bezelHeight": 20}]})",
                                     "tide.json");
  EXPECT_EQ(wall.displays.size(), 6u);
  EXPECT_EQ(wall.width, 3 * 400 + 2 * 10);
  EXPECT_EQ(wall.height, 2 * 300 + 20);
  EXPECT_EQ(wall.displays[5].rect, (voxwall::Rect{820, 320, 400, 300}));
  EXPECT_NEAR(wall.background.r, 1.0, 1e-9);
  EXPECT_NEAR(wall.background.g, 128 / 255.0, 1e-9);
  // Tide's defaults: one screen, no bezel.
  const auto one =
      walls::parseWall(R"({"surfaces": [{"displayWidth": 64, "displayHeight": 32}]})", "t");
  EXPECT_EQ(one.displays.size(), 1u);
  EXPECT_EQ(one.width, 64);
}

TEST(Wall, ExplicitDisplays) {
  const auto wall = walls::parseWall(R"({"wall": "lab", "size": [300, 100], "displays": [
      {"name": "left", "x": 0, "y": 0, "width": 100, "height": 100},
      {"name": "right", "x": 200, "y": 0, "width": 100, "height": 100}]})",
                                     "lab.json");
  EXPECT_EQ(wall.width, 300);
  EXPECT_EQ(wall.displayPixels(), 20000);
}

TEST(Wall, RefusesBadWallsWithAClearMessage) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"{", "not valid JSON"},
      {"[]", "JSON object"},
      {R"({"display": {"width": 0, "height": 10}, "grid": {"columns": 1, "rows": 1}})", "positive"},
      {R"({"display": {"width": 10, "height": 10}, "grid": {"columns": 2, "rows": 1},
           "bezel_px": {"x": -3}})",
       "bezels not negative"},
      {R"({"displays": [{"name": "a", "x": 0, "y": 0, "width": 100, "height": 100},
                        {"name": "b", "x": 50, "y": 50, "width": 100, "height": 100}]})",
       "overlaps display 'a'"},
      {R"({"displays": [{"name": "a", "x": 0, "y": 0, "width": 10, "height": 10},
                        {"name": "a", "x": 20, "y": 0, "width": 10, "height": 10}]})",
       "named twice"},
      {R"({"size": [50, 50], "displays": [{"x": 40, "y": 0, "width": 20, "height": 10}]})",
       "outside"},
      {R"({"display": {"width": 16384, "height": 16384}, "grid": {"columns": 5, "rows": 5}})",
       "beyond the limit"},
      {R"({"display": {"width": 10, "height": 10}, "grid": {"columns": 40, "rows": 40}})",
       "displays, at most"},
      {R"({"display": {"width": 10, "height": 10}, "grid": {"columns": 2, "rows": 2},
           "bezel_mm": {"left": 1}})",
       "width_mm"},
      {R"({"surfaces": [{"displayWidth": 10}]})", "displayHeight"},
      {R"({"display": {"width": 10, "height": 10}, "grid": {"columns": 1, "rows": 1},
           "background": [2, 0, 0]})",
       "background"},
  };
  for (const auto& [text, expected] : bad) {
    try {
      walls::parseWall(text, "w.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << e.what() << " (wanted '" << expected << "')";
      EXPECT_EQ(std::string(e.what()).rfind("w.json", 0), 0u) << e.what();
    }
  }
  EXPECT_THROW(walls::loadWall("/nonexistent/wall.json"), FormatError);
}
