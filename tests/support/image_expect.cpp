#include "support/image_expect.hpp"

#include <gtest/gtest.h>

#include <filesystem>

namespace voxwall::test {

void expectImagesNear(const voxwall::Image& baseline, const voxwall::Image& rendered, int maxAbs,
                      double minPsnrDb, const std::string& label) {
  ASSERT_EQ(baseline.width, rendered.width);
  ASSERT_EQ(baseline.height, rendered.height);
  const auto diff = voxwall::compareImages(baseline, rendered);
  const bool ok = diff.maxAbs <= maxAbs && (minPsnrDb <= 0 || diff.psnrDb >= minPsnrDb);
  EXPECT_TRUE(ok) << label << ": max channel difference " << diff.maxAbs << " (allowed " << maxAbs
                  << "), mean " << diff.meanAbs << ", PSNR " << diff.psnrDb << " dB (needed "
                  << minPsnrDb << ")";
  if (ok) return;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string(info->test_suite_name()) + "." + info->name() +
                     (label.empty() ? "" : "-" + label);
  for (auto& c : name)
    if (c == '/' || c == ' ') c = '_';
  const std::filesystem::path dir = VOXWALL_TEST_OUTPUT_DIR;
  std::filesystem::create_directories(dir);
  voxwall::Image d(baseline.width, baseline.height);
  for (std::size_t i = 0; i < d.pixels.size(); ++i) {
    std::uint32_t out = 0xff000000u;
    for (int c = 0; c < 3; ++c) {
      const int a = int((baseline.pixels[i] >> (8 * c)) & 255),
                b = int((rendered.pixels[i] >> (8 * c)) & 255);
      out |= std::uint32_t(std::min(255, 8 * std::abs(a - b))) << (8 * c);
    }
    d.pixels[i] = out;
  }
  voxwall::writeImage(baseline, (dir / (name + "-baseline.png")).string());
  voxwall::writeImage(rendered, (dir / (name + "-rendered.png")).string());
  voxwall::writeImage(d, (dir / (name + "-diff.png")).string());
  ADD_FAILURE() << "images written to " << (dir / (name + "-*.png")).string();
}

}  // namespace voxwall::test
