#include <gtest/gtest.h>

#include <voxwall/core/errors.hpp>
#include <voxwall/master/camera_path.hpp>

#include "support/temp_dir.hpp"

using namespace voxwall;

TEST(CameraPath, OrbitAddsTheStepPerFrame) {
  node::Orbit start;
  start.azimuthDeg = 10;
  const auto path = master::CameraPath::orbit(start, 5);
  EXPECT_DOUBLE_EQ(path.at(0).azimuthDeg, 10);
  EXPECT_DOUBLE_EQ(path.at(4).azimuthDeg, 30);
  EXPECT_DOUBLE_EQ(path.at(4).distance, start.distance);
}

TEST(CameraPath, OrbitThenZoomTurnsOnceThenApproaches) {
  node::Orbit start;
  start.azimuthDeg = 0, start.distance = 3;
  const auto path = master::CameraPath::orbitThenZoom(start, 4, 2, 1);
  EXPECT_DOUBLE_EQ(path.at(1).azimuthDeg, 90);
  EXPECT_DOUBLE_EQ(path.at(3).distance, 3);
  EXPECT_DOUBLE_EQ(path.at(4).azimuthDeg, 0);
  EXPECT_DOUBLE_EQ(path.at(4).distance, 2);
  EXPECT_DOUBLE_EQ(path.at(5).distance, 1);
  EXPECT_DOUBLE_EQ(path.at(9).distance, 1);
  EXPECT_THROW(master::CameraPath::orbitThenZoom(start, 0, 2, 1), std::invalid_argument);
}

TEST(CameraPath, KeyFramesInterpolateAndHoldAtTheEnds) {
  test::TempDir dir;
  const auto file = dir.path("path.json");
  test::writeFile(file, R"({"keyframes": [
      {"frame": 2, "azimuth": 0, "elevation": 10, "distance": 2, "fov": 30},
      {"frame": 6, "azimuth": 100, "distance": 4},
      {"frame": 8, "elevation": -10}]})");
  const auto path = master::CameraPath::fromJsonFile(file);
  EXPECT_DOUBLE_EQ(path.at(0).azimuthDeg, 0);
  EXPECT_DOUBLE_EQ(path.at(4).azimuthDeg, 50);
  EXPECT_DOUBLE_EQ(path.at(4).distance, 3);
  EXPECT_DOUBLE_EQ(path.at(4).elevationDeg, 10);  // carried over from the previous key
  EXPECT_DOUBLE_EQ(path.at(7).azimuthDeg, 100);
  EXPECT_DOUBLE_EQ(path.at(7).elevationDeg, 0);
  EXPECT_DOUBLE_EQ(path.at(20).elevationDeg, -10);
}

TEST(CameraPath, RejectsMalformedFiles) {
  test::TempDir dir;
  const std::vector<std::string> bad = {
      "not json",
      R"({"frames": []})",
      R"({"keyframes": []})",
      R"({"keyframes": [{"azimuth": 3}]})",
      R"({"keyframes": [{"frame": 3}, {"frame": 3}]})",
      R"({"keyframes": [{"frame": 0, "distance": -1}]})",
      R"({"keyframes": [{"frame": 0, "fov": 180}]})",
      R"({"keyframes": [{"frame": 0, "azimuth": "left"}]})",
  };
  for (const auto& text : bad) {
    const auto file = dir.path("bad.json");
    test::writeFile(file, text);
    EXPECT_THROW(master::CameraPath::fromJsonFile(file), FormatError) << text;
  }
  EXPECT_THROW(master::CameraPath::fromJsonFile(dir.path("missing.json")), FormatError);
}
