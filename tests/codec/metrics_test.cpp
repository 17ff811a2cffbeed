#include <gtest/gtest.h>

#include <cmath>
#include <voxwall/codec/metrics.hpp>

using namespace voxwall::codec;

TEST(Metrics, PsnrOfKnownError) {
  Volume a = Volume::allocate({10, 10, 1}, ScalarType::UInt8);
  for (std::size_t i = 0; i < 100; ++i) a.as<std::uint8_t>()[i] = std::uint8_t(i * 2);
  a.computeRange();  // peak 198
  Volume b = a;
  EXPECT_TRUE(std::isinf(psnr(a, b)));
  b.as<std::uint8_t>()[0] += 10;  // MSE = 100 / 100 = 1
  EXPECT_NEAR(psnr(a, b), 10.0 * std::log10(198.0 * 198.0), 1e-9);
  EXPECT_NEAR(bitsPerVoxel(100, a), 8.0, 1e-12);
  Volume c = Volume::allocate({9, 10, 1}, ScalarType::UInt8);
  EXPECT_THROW(psnr(a, c), std::invalid_argument);
}
