#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
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

TEST(TransferFunction, APresetWithoutOpacityGetsTheDocumentedCurve) {
  const auto tf = TransferFunction::fromParaViewJsonText(
      R"({"ColorSpace": "Diverging", "RGBPoints": [-1, 0, 0, 1, 1, 1, 0, 0]})", "x.json");
  ASSERT_EQ(tf.warnings.size(), 1u);  // no Points (Diverging is interpolated as ParaView does)
  EXPECT_NE(tf.warnings[0].find("transparent below 30%"), std::string::npos) << tf.warnings[0];
  EXPECT_FALSE(tf.ownOpacity);
  EXPECT_EQ(tf.colorSpace, ColorSpace::Diverging);
  EXPECT_TRUE(tf.normalized);  // [-1, 1], as ParaView's bundled presets are written
  double rgba[4];
  tf.evaluate(-0.5, rgba);  // 25% of the range: still transparent
  EXPECT_DOUBLE_EQ(rgba[3], 0.0);
  tf.evaluate(1, rgba);
  EXPECT_DOUBLE_EQ(rgba[3], 0.8);
}

TEST(TransferFunction, RefusesMalformedPresets) {
  for (const char* text : {"not json", "[]", R"({"RGBPoints": [0, 0, 0]})",
                           R"({"RGBPoints": [1, 0, 0, 0, 0, 1, 1, 1]})",
                           R"({"RGBPoints": [0, 0, 0, 2]})", R"({"RGBPoints": [0, 0, 0, "a"]})",
                           R"({"RGBPoints": [0, 0, 0, 0], "Points": [0, 1.5, 0.5, 0]})",
                           // A number too large for a double (found by config_files_fuzz).
                           R"({"RGBPoints": [1.5E22222222, 0, 0, 0]})"}) {
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

// The hu-* presets stay on Hounsfield units whatever the data's range: bone is opaque at 1000 HU
// and air and soft tissue are not, on a CT of -1024..3071 as on one cropped to 0..2000.
TEST(TransferFunction, HounsfieldPresetsStayOnHounsfieldUnits) {
  for (const char* name : {"hu-bone", "hu-soft-tissue", "hu-lung", "hu-angio", "hu-skin"}) {
    auto tf = TransferFunction::preset(name);
    EXPECT_TRUE(tf.hounsfield) << name;
    EXPECT_FALSE(tf.normalized) << name;
    const double lo = tf.domainMin(), hi = tf.domainMax();
    EXPECT_NE(tf.placeOnData(0, 2000, std::nullopt).find("Hounsfield units"), std::string::npos);
    EXPECT_EQ(tf.domainMin(), lo) << name;
    EXPECT_EQ(tf.domainMax(), hi) << name;
  }
  auto bone = TransferFunction::preset("hu-bone");
  bone.placeOnData(-1024, 3071, std::nullopt);
  double air[4], soft[4], cortical[4];
  bone.evaluate(-1000, air), bone.evaluate(40, soft), bone.evaluate(1000, cortical);
  EXPECT_EQ(air[3], 0);
  EXPECT_EQ(soft[3], 0);
  EXPECT_GT(cortical[3], 0.7);
  auto lung = TransferFunction::preset("hu-lung");
  double parenchyma[4], muscle[4];
  lung.evaluate(-700, parenchyma), lung.evaluate(40, muscle);
  EXPECT_GT(parenchyma[3], 0.1);
  EXPECT_EQ(muscle[3], 0);
}

// VTK's vtkColorTransferFunction (what ParaView applies) at 20 points of maps in every colour
// space, computed by tests/tools/vtk_colormap_oracle.py with Debian's python3-vtk9.
TEST(TransferFunction, ColourSpacesMatchVtk) {
  std::ifstream in(VOXWALL_TEST_DATA_DIR "/vtk_colormaps.json");
  ASSERT_TRUE(in) << "tests/data/vtk_colormaps.json";
  const auto oracle = nlohmann::json::parse(in);
  std::set<std::string> spaces;
  for (const auto& map : oracle["maps"]) {
    const auto tf = TransferFunction::fromParaViewJsonText(map.dump(), "oracle");
    spaces.insert(map["ColorSpace"].get<std::string>());
    ASSERT_EQ(map["samples"].size(), 20u);
    for (const auto& sample : map["samples"]) {
      double rgba[4];
      tf.evaluate(sample[0].get<double>(), rgba);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(rgba[c], sample[c + 1].get<double>(), 1.0 / 255)
            << map["Name"].get<std::string>() << " at " << sample[0].get<double>() << " channel "
            << c;
    }
  }
  for (const char* space : {"Diverging", "Lab", "CIELAB", "HSV", "Wrapped HSV", "RGB", "Step"})
    EXPECT_EQ(spaces.count(space), 1u) << space;
}

TEST(TransferFunction, LabRoundTripsAndDivergingPassesThroughWhite) {
  for (const Rgb c : {Rgb{0, 0, 0}, Rgb{1, 1, 1}, Rgb{0.2, 0.5, 0.9}, Rgb{1, 0, 0}}) {
    const Rgb back = labToRgb(rgbToLab(c));
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(back[i], c[i], 1e-3);
  }
  // Moreland's cool-warm: the middle is a light grey, not the dull grey of RGB interpolation.
  const Rgb blue{0.231373, 0.298039, 0.752941}, red{0.705882, 0.0156863, 0.14902};
  const Rgb mid = interpolateColor(ColorSpace::Diverging, blue, red, 0.5);
  const Rgb rgbMid = interpolateColor(ColorSpace::Rgb, blue, red, 0.5);
  EXPECT_GT(mid[1], 0.8);
  EXPECT_LT(rgbMid[1], 0.2);
}

namespace {
const char* kTwoMaps = R"([
  {"Name": "Warm", "ColorSpace": "Lab", "RGBPoints": [0, 1, 0.9, 0.5, 1, 0.6, 0, 0]},
  {"Name": "Cold", "RGBPoints": [0, 0.8, 0.9, 1, 1, 0, 0, 0.5],
   "Points": [0, 0, 0.5, 0, 0.5, 0.1, 0.5, 0, 1, 0.9, 0.5, 0]}])";
}

TEST(TransferFunction, FilesWithSeveralMapsArePickedByName) {
  const auto cold = TransferFunction::fromParaViewJsonText(kTwoMaps, "two.json", "Cold");
  EXPECT_EQ(cold.name, "Cold");
  EXPECT_TRUE(cold.ownOpacity);
  EXPECT_EQ(TransferFunction::fromParaViewJsonText(kTwoMaps, "two.json", "Warm").colorSpace,
            ColorSpace::Lab);
  try {
    TransferFunction::fromParaViewJsonText(kTwoMaps, "two.json");
    ADD_FAILURE() << "a two-map file without a name was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("2 colour maps ('Warm', 'Cold')"), std::string::npos)
        << e.what();
  }
  try {
    TransferFunction::fromParaViewJsonText(kTwoMaps, "two.json", "Hot");
    ADD_FAILURE() << "an unknown name was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("no colour map named 'Hot'"), std::string::npos);
  }
}

TEST(TransferFunction, NormalizedMapsAreStretchedOverTheDataAndDataMapsStay) {
  auto normalized = TransferFunction::fromParaViewJsonText(kTwoMaps, "two.json", "Cold");
  ASSERT_TRUE(normalized.normalized);
  const auto said = normalized.placeOnData(10, 250, std::nullopt);
  EXPECT_NE(said.find("stretched over the data range 10..250"), std::string::npos) << said;
  EXPECT_DOUBLE_EQ(normalized.domainMin(), 10);
  EXPECT_DOUBLE_EQ(normalized.domainMax(), 250);
  auto state = TransferFunction::fromParaViewJsonText(
      R"({"RGBPoints": [37.5, 0, 0, 1, 276.8, 1, 0, 0], "Points": [37.5, 0, 0.5, 0, 276.8, 1, 0.5, 0]})",
      "state.json");
  EXPECT_FALSE(state.normalized);
  EXPECT_NE(state.placeOnData(0, 1000, std::nullopt).find("in data values"), std::string::npos);
  EXPECT_DOUBLE_EQ(state.domainMin(), 37.5);
  state.placeOnData(0, 1000, std::pair{0.0, 100.0});
  EXPECT_DOUBLE_EQ(state.domainMax(), 100.0);
}

TEST(TransferFunction, OpacityFromAnotherMapReplacesTheDefaultCurveAndItsWarning) {
  auto colours = TransferFunction::fromParaViewJsonText(
      R"({"Name": "C", "RGBPoints": [0, 0, 0, 1, 1, 1, 0, 0]})", "c.json");
  ASSERT_FALSE(colours.ownOpacity);
  ASSERT_EQ(colours.warnings, std::vector<std::string>{colours.noOpacityWarning()});
  const auto curve = TransferFunction::fromParaViewJsonText(kTwoMaps, "two.json", "Cold");
  colours.takeOpacityFrom(curve);
  EXPECT_TRUE(colours.ownOpacity);
  EXPECT_TRUE(colours.warnings.empty());
  ASSERT_EQ(colours.opacities.size(), curve.opacities.size());
  EXPECT_DOUBLE_EQ(colours.opacities[1].opacity, 0.1);
}

TEST(TransferFunction, SpecsNameABuiltInAFileOrAMapInAFile) {
  const auto dir = std::filesystem::temp_directory_path() / "voxwall-tf-spec-test";
  std::filesystem::create_directories(dir);
  const auto file = (dir / "maps.json").string();
  std::ofstream(file) << kTwoMaps;
  EXPECT_EQ(TransferFunction::splitSpec("mri").file, "");
  EXPECT_EQ(TransferFunction::splitSpec("mri").name, "mri");
  EXPECT_EQ(TransferFunction::splitSpec(file).file, file);
  const auto parts = TransferFunction::splitSpec(file + ":Cold");
  EXPECT_EQ(parts.file, file);
  EXPECT_EQ(parts.name, "Cold");
  EXPECT_EQ(TransferFunction::load(file + ":Cold").name, "Cold");
  std::filesystem::remove_all(dir);
}
