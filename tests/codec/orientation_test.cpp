// Orientation: letters, the readers' conversions to LPS, and the writers that keep it.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/volume_source.hpp>

#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using test::TempDir;

namespace {

void expectOrientationNear(const Orientation& a, const Orientation& b, double tolerance) {
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      EXPECT_NEAR(a.direction[c][r], b.direction[c][r], tolerance)
          << "column " << c << " row " << r;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a.origin[i], b.origin[i], tolerance) << "origin " << i;
}

Volume ramp(glm::ivec3 dims, glm::dvec3 spacing) {
  Volume v = Volume::allocate(dims, ScalarType::Int16, spacing);
  auto values = v.as<std::int16_t>();
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = std::int16_t(i % 1000);
  v.computeRange();
  return v;
}

}  // namespace

TEST(Orientation, LettersNameTheAxesAndParseBack) {
  EXPECT_EQ(orientationLetters(glm::dmat3(1.0)), "LPS");
  const glm::dmat3 ras = parseOrientationLetters("RAS");
  EXPECT_EQ(ras, glm::dmat3(glm::dvec3(-1, 0, 0), glm::dvec3(0, -1, 0), glm::dvec3(0, 0, 1)));
  EXPECT_EQ(parseOrientationLetters("las"), parseOrientationLetters("LAS"));
  // Every one of the 48 axis-aligned orientations goes to letters and back.
  int seen = 0;
  const std::string letters[3][2] = {{"L", "R"}, {"P", "A"}, {"S", "I"}};
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : perms)
    for (int signs = 0; signs < 8; ++signs) {
      std::string name;
      for (int a = 0; a < 3; ++a) name += letters[p[a]][(signs >> a) & 1];
      const glm::dmat3 m = parseOrientationLetters(name);
      EXPECT_TRUE(orientationProblem(m).empty()) << name;
      EXPECT_EQ(orientationLetters(m), name);
      ++seen;
    }
  EXPECT_EQ(seen, 48);
  // An oblique axis gets the letter of its largest component.
  const double c = std::cos(0.3), s = std::sin(0.3);
  EXPECT_EQ(orientationLetters(
                glm::dmat3(glm::dvec3(c, s, 0), glm::dvec3(-s, c, 0), glm::dvec3(0, 0, 1))),
            "LPS");
  for (const char* bad : {"RRS", "RA", "RASI", "XYZ", "", "LPL"})
    EXPECT_THROW(parseOrientationLetters(bad), std::invalid_argument) << bad;
}

TEST(Orientation, OnlyRotationsAndMirrorsAreDirections) {
  EXPECT_TRUE(orientationProblem(glm::dmat3(1.0)).empty());
  EXPECT_TRUE(orientationProblem(parseOrientationLetters("AIR")).empty());
  EXPECT_NE(orientationProblem(glm::dmat3(2.0)).find("unit length"), std::string::npos);
  glm::dmat3 shear(1.0);
  shear[1] = glm::normalize(glm::dvec3(0.3, 1, 0));
  EXPECT_NE(orientationProblem(shear).find("not orthogonal"), std::string::npos);
  const glm::dmat3 fixed = orthonormalized(shear);
  EXPECT_TRUE(orientationProblem(fixed).empty());
  EXPECT_EQ(fixed[0], glm::dvec3(1, 0, 0));  // x kept, y made orthogonal to it
  glm::dmat3 nan(1.0);
  nan[2][2] = std::nan("");
  EXPECT_NE(orientationProblem(nan).find("not finite"), std::string::npos);
}

// NIfTI stores RAS, NRRD names its space: both come back as the LPS matrix they were written
// with, and a NIfTI read a slab at a time says the same as one read whole.
TEST(Orientation, NiftiAndNrrdKeepTheMatrix) {
  TempDir dir;
  Volume v = ramp({6, 5, 4}, {0.5, 0.75, 2.0});
  v.orientation.direction = parseOrientationLetters("AIR");  // x anterior, y inferior, z right
  v.orientation.origin = {10.25, -3.5, 42};
  for (const char* name : {"a.nii", "a.nii.gz", "a.nrrd", "a.nhdr"}) {
    SCOPED_TRACE(name);
    writeVolume(v, dir.path(name));
    const Volume back = readVolume(dir.path(name));
    expectOrientationNear(back.orientation, v.orientation, 1e-5);
    EXPECT_NEAR(back.spacing.x, 0.5, 1e-6);
    EXPECT_NEAR(back.spacing.z, 2.0, 1e-6);
    EXPECT_EQ(orientationLetters(back.orientation.direction), "AIR");
    Progress quiet;
    const auto source = openVolumeSource(dir.path(name), {}, quiet);
    expectOrientationNear(source->orientation, v.orientation, 1e-5);
    expectOrientationNear(source->headerVolume().orientation, v.orientation, 1e-5);
  }
}

// A NRRD in NIfTI's RAS space: its directions and origin flip x and y on the way to LPS.
TEST(Orientation, NrrdSpacesConvertToLps) {
  TempDir dir;
  const auto write = [&](const std::string& name, const std::string& space) {
    std::ofstream out(dir.path(name), std::ios::binary);
    out << "NRRD0004\ntype: uint8\ndimension: 3\nspace: " << space
        << "\nsizes: 2 2 2\nspace directions: (0,0,1.5) (0,-2,0) (1,0,0)\nspace origin: "
           "(10,20,30)\nencoding: raw\n\n";
    for (int i = 0; i < 8; ++i) out.put(char(i * 10));
  };
  write("ras.nrrd", "right-anterior-superior");
  const Volume ras = readVolume(dir.path("ras.nrrd"));
  // x: +1.5 along S; y: -2 along A = +2 along P; z: +1 along R = -1 along L.
  EXPECT_EQ(orientationLetters(ras.orientation.direction), "SPR");
  EXPECT_NEAR(ras.spacing.x, 1.5, 1e-12);
  EXPECT_NEAR(ras.spacing.y, 2.0, 1e-12);
  EXPECT_EQ(ras.orientation.origin, glm::dvec3(-10, -20, 30));

  write("lps.nrrd", "left-posterior-superior");
  const Volume lps = readVolume(dir.path("lps.nrrd"));
  EXPECT_EQ(orientationLetters(lps.orientation.direction), "SAL");
  EXPECT_EQ(lps.orientation.origin, glm::dvec3(10, 20, 30));
}

// Raw files and slice stacks say nothing: LPS, unless the layout names an orientation.
TEST(Orientation, RawIsLpsUnlessTold) {
  TempDir dir;
  const Volume v = ramp({4, 3, 2}, {1, 1, 1});
  writeVolume(v, dir.path("v.raw"));
  RawLayout layout;
  layout.dims = v.dims, layout.type = v.type;
  EXPECT_EQ(readVolume(dir.path("v.raw"), layout).orientation, Orientation{});
  layout.orientation.direction = parseOrientationLetters("RAS");
  EXPECT_EQ(orientationLetters(readVolume(dir.path("v.raw"), layout).orientation.direction), "RAS");
  Progress quiet;
  EXPECT_EQ(
      orientationLetters(openVolumeSource(dir.path("v.raw"), layout, quiet)->orientation.direction),
      "RAS");
}
