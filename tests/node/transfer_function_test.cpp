#include <gtest/gtest.h>

#include <voxwall/core/errors.hpp>
#include <voxwall/node/transfer_function.hpp>

using namespace voxwall;
using namespace voxwall::node;

TEST(TransferFunction, ReadsAParaViewPresetArray) {
  const auto tf = TransferFunction::fromParaViewJsonText(R"([
    {"Name": "Other", "Points": [0, 0, 0.5, 0]},
    {"Name": "Bone", "ColorSpace": "RGB",
     "RGBPoints": [0, 0, 0, 0,  100, 1, 0.5, 0.25,  200, 1, 1, 1],
     "Points": [0, 0, 0.5, 0,  50, 0, 0.5, 0,  200, 0.8, 0.5, 0]}])",
                                                         "bone.json");
  EXPECT_EQ(tf.name, "Bone");
  ASSERT_EQ(tf.colors.size(), 3u);
  ASSERT_EQ(tf.opacities.size(), 3u);
  EXPECT_TRUE(tf.warnings.empty());
  double rgba[4];
  tf.evaluate(50, rgba);
  EXPECT_DOUBLE_EQ(rgba[0], 0.5);
  EXPECT_DOUBLE_EQ(rgba[3], 0.0);
  tf.evaluate(125, rgba);
  EXPECT_DOUBLE_EQ(rgba[3], 0.4);
  EXPECT_DOUBLE_EQ(tf.domainMin(), 0.0);
  EXPECT_DOUBLE_EQ(tf.domainMax(), 200.0);
}

TEST(TransferFunction, WarnsAboutWhatItApproximates) {
  const auto tf = TransferFunction::fromParaViewJsonText(
      R"({"ColorSpace": "Diverging", "RGBPoints": [-1, 0, 0, 1, 1, 1, 0, 0]})", "x.json");
  ASSERT_EQ(tf.warnings.size(), 2u);  // no Points, Diverging interpolated in RGB
  double rgba[4];
  tf.evaluate(1, rgba);
  EXPECT_DOUBLE_EQ(rgba[3], 1.0);
}

TEST(TransferFunction, RefusesMalformedPresets) {
  for (const char* text : {"not json", "[]", R"({"RGBPoints": [0, 0, 0]})",
                           R"({"RGBPoints": [1, 0, 0, 0, 0, 1, 1, 1]})",
                           R"({"RGBPoints": [0, 0, 0, 2]})", R"({"RGBPoints": [0, 0, 0, "a"]})",
                           R"({"RGBPoints": [0, 0, 0, 0], "Points": [0, 1.5, 0.5, 0]})"}) {
    try {
      TransferFunction::fromParaViewJsonText(text, "t.json");
      ADD_FAILURE() << "accepted " << text;
    } catch (const FormatError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("t.json: ", 0), 0u) << e.what();
    }
  }
  EXPECT_THROW(TransferFunction::fromParaViewJson("/nonexistent.json"), FormatError);
}

TEST(TransferFunction, MidpointAndSharpnessShapeTheOpacity) {
  TransferFunction tf;
  tf.colors = {{0, 1, 1, 1}};
  tf.opacities = {{0, 0, 0.25, 0}, {1, 1}};
  double rgba[4];
  tf.evaluate(0.25, rgba);  // the midpoint maps to half way
  EXPECT_NEAR(rgba[3], 0.5, 1e-12);
  tf.opacities = {{0, 0, 0.5, 1.0}, {1, 1}};  // sharpness 1: a step at the midpoint
  tf.evaluate(0.49, rgba);
  EXPECT_EQ(rgba[3], 0.0);
  tf.evaluate(0.51, rgba);
  EXPECT_EQ(rgba[3], 1.0);
  tf.opacities = {{0, 0, 0.5, 0.5}, {1, 1}};  // in between: monotone, symmetric about 0.5
  double lo[4], hi[4];
  tf.evaluate(0.3, lo);
  tf.evaluate(0.7, hi);
  EXPECT_NEAR(lo[3] + hi[3], 1.0, 1e-9);
  EXPECT_LT(lo[3], 0.3);
}

TEST(TransferFunction, BakesOpacityCorrectedForTheStep) {
  TransferFunction tf;
  tf.colors = {{0, 1, 1, 1}, {1, 1, 1, 1}};
  tf.opacities = {{0, 0.75}, {1, 0.75}};
  const auto lut = tf.bake(0, 1, 0.5, 16);
  EXPECT_NEAR(lut.entries[3].a, 0.5f, 1e-6f);  // 1 - (1 - 0.75)^0.5
  EXPECT_THROW(tf.bake(0, 1, 0.0), std::invalid_argument);
}

TEST(TransferFunction, PresetsRescaleOntoTheData) {
  for (auto& name : TransferFunction::presetNames()) {
    const auto tf = TransferFunction::preset(name).rescaled(-1000, 3000);
    EXPECT_DOUBLE_EQ(tf.domainMin(), -1000) << name;
    EXPECT_DOUBLE_EQ(tf.domainMax(), 3000) << name;
    EXPECT_EQ(tf.bake(-1000, 3000, 0.25).view().size, 4096);
  }
  EXPECT_THROW(TransferFunction::preset("nope"), std::invalid_argument);
}
