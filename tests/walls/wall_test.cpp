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
  const auto tide = walls::loadWall(kWalls + "/tide-reference.json");
  EXPECT_EQ(tide.width, 7722);
  EXPECT_EQ(tide.height, 3264);
  EXPECT_EQ(tide.displays.size(), 12u);
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

namespace {
// Tide's reference surface (its own tests' configuration): 2 x 3 screens of 2 x 1 displays.
const char* kTideReference = R"({"surfaces": [{"displayWidth": 1920, "displayHeight": 1080,
    "displaysPerScreenX": 2, "displaysPerScreenY": 1, "screenCountX": 2, "screenCountY": 3,
    "bezelWidth": 14, "bezelHeight": 12}]})";

const walls::Display& displayNamed(const walls::Wall& wall, const std::string& name) {
  for (const auto& d : wall.displays)
    if (d.name == name) return d;
  throw std::runtime_error("no display " + name);
}
}  // namespace

TEST(Wall, TideReferenceSurfaceHasTidesGeometry) {
  const auto wall = walls::parseWall(kTideReference, "tide.json");
  // Tide: screen 3854x1080 (2 * 1920 + 14), surface 2 * 3854 + 14 by 3 * 1080 + 2 * 12.
  EXPECT_EQ(wall.displays.size(), 12u);
  EXPECT_EQ(wall.width, 7722);
  EXPECT_EQ(wall.height, 3264);
  EXPECT_FALSE(wall.overlapping);
  // Tide's screen rectangles: screen (i, j) at (i * (3854 + 14), j * (1080 + 12)).
  EXPECT_EQ(displayNamed(wall, "s0-1_d0-0").rect, (voxwall::Rect{0, 1092, 1920, 1080}));
  EXPECT_EQ(displayNamed(wall, "s1-2_d0-0").rect, (voxwall::Rect{3868, 2184, 1920, 1080}));
  // The second display of a screen sits one display and one bezel to the right.
  EXPECT_EQ(displayNamed(wall, "s1-0_d1-0").rect, (voxwall::Rect{3868 + 1934, 0, 1920, 1080}));
  EXPECT_EQ(wall.displayPixels(), 12ll * 1920 * 1080);
  EXPECT_NE(walls::describeSurface(wall, 0).find("7722x3264"), std::string::npos);
  // Displays run row by row, left to right.
  EXPECT_EQ(wall.displays[1].name, "s0-0_d1-0");
  EXPECT_EQ(wall.displays[4].name, "s0-1_d0-0");
}

TEST(Wall, TideXmlConfigurationGivesTheSameSurface) {
  const auto xml = walls::parseWall(R"(<?xml version="1.0"?>
<configuration>
  <dimensions numScreensX="2" numScreensY="3" displayWidth="1920" displayHeight="1080"
              bezelWidth="14" bezelHeight="12" displaysPerScreenX="2" displaysPerScreenY="1"
              fullscreen="1"/>
  <background color="#102030"/>
  <process host="localhost"><screen display=":0.0" x="0" y="0" i="0" j="0"/></process>
</configuration>)",
                                    "tide.xml");
  const auto json = walls::parseWall(kTideReference, "tide.json");
  EXPECT_EQ(xml.width, json.width);
  EXPECT_EQ(xml.height, json.height);
  ASSERT_EQ(xml.displays.size(), json.displays.size());
  for (std::size_t i = 0; i < xml.displays.size(); ++i) {
    EXPECT_EQ(xml.displays[i].name, json.displays[i].name);
    EXPECT_EQ(xml.displays[i].rect, json.displays[i].rect);
  }
  EXPECT_NEAR(xml.background.b, 0x30 / 255.0, 1e-9);
  // Tide before 1.4: numTilesWidth/Height, screenWidth/Height, mullionWidth/Height.
  const auto old = walls::parseWall(R"(<configuration><dimensions numTilesWidth="3"
      numTilesHeight="1" screenWidth="100" screenHeight="50" mullionWidth="4"/></configuration>)",
                                    "old.xml");
  EXPECT_EQ(old.width, 3 * 100 + 2 * 4);
  EXPECT_EQ(old.height, 50);
}

TEST(Wall, NegativeBezelsMakeOverlappingDisplays) {
  const auto wall = walls::parseWall(R"({"surfaces": [{"displayWidth": 100, "displayHeight": 50,
      "screenCountX": 3, "screenCountY": 2, "bezelWidth": -10, "bezelHeight": -5}]})",
                                     "blend.json");
  EXPECT_TRUE(wall.overlapping);
  EXPECT_EQ(wall.width, 3 * 100 - 2 * 10);
  EXPECT_EQ(wall.height, 2 * 50 - 5);
  EXPECT_EQ(displayNamed(wall, "s1-1").rect, (voxwall::Rect{90, 45, 100, 50}));
  // Shared pixels count once: the union is the whole virtual screen.
  EXPECT_EQ(wall.displayPixels(), (long long)wall.width * wall.height);
}

TEST(Wall, EverySurfaceOfATideConfigurationCanBePicked) {
  const std::string text = R"({"surfaces": [
      {"displayWidth": 64, "displayHeight": 32, "screenCountX": 2},
      {"displayWidth": 40, "displayHeight": 30, "screenCountY": 3, "bezelHeight": 2}]})";
  const auto all = walls::parseWalls(text, "two.json");
  ASSERT_EQ(all.size(), 2u);
  const auto second = walls::parseWall(text, "two.json", 1);
  EXPECT_EQ(second.width, 40);
  EXPECT_EQ(second.height, 94);
  EXPECT_NE(second.id, all[0].id);  // a sink showing one surface refuses a job for the other
  try {
    walls::parseWall(text, "two.json", 2);
    ADD_FAILURE() << "surface 2 accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("2 surface(s)"), std::string::npos) << e.what();
  }
}

TEST(Wall, OverlapsInVoxwallFilesNeedToBeSaid) {
  const std::string displays = R"("size": [190, 50], "displays": [
      {"name": "left", "x": 0, "y": 0, "width": 100, "height": 50},
      {"name": "right", "x": 90, "y": 0, "width": 100, "height": 50}])";
  try {
    walls::parseWall("{" + displays + "}", "w.json");
    ADD_FAILURE() << "overlap accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("\"overlap\": true"), std::string::npos) << e.what();
  }
  const auto wall = walls::parseWall("{\"overlap\": true, " + displays + "}", "w.json");
  EXPECT_TRUE(wall.overlapping);
  EXPECT_EQ(wall.displayPixels(), 190 * 50);
}

TEST(Wall, TideRefusalsNameTheFileAndTheField) {
  const std::pair<std::string, std::string> bad[] = {
      {R"({"surfaces": [{"displayWidth": 10, "displayHeight": 10, "displaysPerScreenX": 0}]})",
       "w.json: surfaces[0].displaysPerScreenX"},
      {R"({"surfaces": [{"displayWidth": 10, "displayHeight": 10},
                        {"displayWidth": 10, "displayHeight": 10, "bezelWidth": -10}]})",
       "w.json: surfaces[1].bezelWidth"},
      {R"({"surfaces": [{"displayWidth": 10, "displayHeight": 10, "screenCountY": "2"}]})",
       "w.json: surfaces[0].screenCountY"},
      {R"({"surfaces": [{"displayWidth": 10, "displayHeight": 10,
                         "background": {"color": "red"}}]})",
       "w.json: surfaces[0].background.color"},
      {R"({"surfaces": [{"displayWidth": 16000, "displayHeight": 10, "screenCountX": 8}]})",
       "beyond the limit"},
      {R"({"surfaces": []})", "w.json: \"surfaces\""},
      {R"(<configuration><dimensions displayHeight="10"/></configuration>)",
       "w.json: <dimensions> has no displayWidth"},
      {R"(<configuration><dimensions displayWidth="10x" displayHeight="10"/></configuration>)",
       "w.json: dimensions@displayWidth"},
      {R"(<configuration><dimensions displayWidth="10" displayHeight="10")", "not valid XML"},
  };
  for (const auto& [text, expected] : bad) {
    try {
      walls::parseWalls(text, "w.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << e.what() << " (wanted '" << expected << "')";
    }
  }
}
