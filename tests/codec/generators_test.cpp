#include <gtest/gtest.h>

#include <cmath>
#include <voxwall/codec/generators.hpp>

using namespace voxwall::codec;

TEST(Generators, MengerSpongeKeeps20OfEvery27Cubes) {
  for (int level = 0; level <= 3; ++level) {
    const Volume v = generateMenger(level);
    int n = 1, solid = 1;
    for (int i = 0; i < level; ++i) n *= 3, solid *= 20;
    ASSERT_EQ(v.dims, glm::ivec3(n));
    std::size_t count = 0;
    for (auto x : v.as<std::uint8_t>()) count += x == 255;
    EXPECT_EQ(count, std::size_t(solid)) << "level " << level;
  }
  const Volume v = generateMenger(2);
  EXPECT_EQ(v.as<std::uint8_t>()[v.index(0, 0, 0)], 255);  // corner cube
  EXPECT_EQ(v.as<std::uint8_t>()[v.index(4, 0, 0)], 255);  // edge cube of level 1
  EXPECT_EQ(v.as<std::uint8_t>()[v.index(4, 4, 0)], 0);    // face centre of level 1: carved
  EXPECT_EQ(v.as<std::uint8_t>()[v.index(4, 4, 4)], 0);    // body centre: carved
  EXPECT_EQ(v.as<std::uint8_t>()[v.index(1, 1, 0)], 0);    // face centre of level 2: carved
  EXPECT_THROW(generateMenger(8), std::invalid_argument);
}

TEST(Generators, MarschnerLobbMatchesTheFormula) {
  const Volume v = generateMarschnerLobb(41, ScalarType::Float32);
  // At the origin: r = 0, rho_r = cos(12 pi) = 1, so (1 - 0 + 0.25 * 2) / 2.5 = 0.6.
  EXPECT_NEAR(v.as<float>()[v.index(20, 20, 20)], 0.6f, 1e-6f);
  // At z = 1 (top face) and r = 0: (1 - 1 + 0.5) / 2.5 = 0.2.
  EXPECT_NEAR(v.as<float>()[v.index(20, 20, 40)], 0.2f, 1e-6f);
  EXPECT_GE(v.valueMin, 0.0);
  EXPECT_LE(v.valueMax, 1.0);
  // Symmetric under x -> -x.
  for (int x = 0; x < 41; ++x)
    EXPECT_EQ(v.as<float>()[v.index(x, 7, 9)], v.as<float>()[v.index(40 - x, 7, 9)]);
}

TEST(Generators, SheppLoganHasSkullBrainAndVentricles) {
  const Volume v = generateSheppLogan(65, ScalarType::Float32);
  auto at = [&](double x, double y, double z) {
    auto idx = [](double c) { return int(std::lround((c + 1.0) * 32.0)); };
    return v.as<float>()[v.index(idx(x), idx(y), idx(z))];
  };
  EXPECT_FLOAT_EQ(at(0, 0.9, 0), 1.0f);         // skull: only the outer ellipsoid
  EXPECT_NEAR(at(0, 0, 0), 0.2f, 1e-6f);        // brain: 1 - 0.8
  EXPECT_NEAR(at(0.22, 0, 0), 0.0f, 1e-6f);     // right ventricle: 1 - 0.8 - 0.2
  EXPECT_FLOAT_EQ(at(0.95, 0.95, 0.95), 0.0f);  // outside the head
  const Volume u8 = generateSheppLogan(32);
  EXPECT_EQ(u8.type, ScalarType::UInt8);
  EXPECT_EQ(u8.valueMax, 255);
}
