#include <gtest/gtest.h>

#include <random>
#include <voxwall/codec/generators.hpp>
#include <voxwall/master/frame_loop.hpp>

#include "support/temp_dir.hpp"

using namespace voxwall;

TEST(GridTiles, CoverTheScreenExactlyOnce) {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 200; ++trial) {
    const int w = 1 + int(rng() % 300), h = 1 + int(rng() % 300);
    const int tx = 1 + int(rng() % std::min(w, 9)), ty = 1 + int(rng() % std::min(h, 9));
    std::vector<int> covered(std::size_t(w) * std::size_t(h), 0);
    for (auto& r : master::gridTiles(w, h, tx, ty)) {
      ASSERT_GT(r.width, 0);
      ASSERT_GT(r.height, 0);
      for (int y = r.y; y < r.y + r.height; ++y)
        for (int x = r.x; x < r.x + r.width; ++x)
          covered[std::size_t(y) * std::size_t(w) + std::size_t(x)]++;
    }
    for (int c : covered) ASSERT_EQ(c, 1) << w << "x" << h << " in " << tx << "x" << ty;
  }
  EXPECT_THROW(master::gridTiles(4, 4, 5, 1), std::invalid_argument);
  EXPECT_THROW(master::gridTiles(4, 4, 0, 1), std::invalid_argument);
}

TEST(RenderSequence, WritesOneFilePerFrameAndOrbits) {
  test::TempDir dir;
  const auto volume = node::RenderVolume::fromVolume(codec::generateMenger(3), 8);
  master::SequenceSettings seq;
  seq.width = 40, seq.height = 30, seq.frames = 3, seq.orbitStepDeg = 20;
  seq.outDir = dir.path("frames");
  auto backend = node::makeCpuBackend(2);
  std::vector<master::FrameReport> reports;
  master::renderSequence(*backend, volume, node::TransferFunction::preset("grey").rescaled(0, 255),
                         {}, seq, [&](const master::FrameReport& r) { reports.push_back(r); });
  ASSERT_EQ(reports.size(), 3u);
  for (int f = 0; f < 3; ++f) {
    EXPECT_TRUE(std::filesystem::exists(reports[std::size_t(f)].path));
    EXPECT_NE(reports[std::size_t(f)].path.find("frame_0000" + std::to_string(f) + ".png"),
              std::string::npos);
    EXPECT_GT(reports[std::size_t(f)].samples, 0u);
  }
  // Frames differ because the camera moved.
  EXPECT_NE(node::readImage(reports[0].path).pixels, node::readImage(reports[1].path).pixels);
  // Nothing but the frames is left in the directory (no temporaries).
  int files = 0;
  for (auto& e : std::filesystem::directory_iterator(seq.outDir)) files += e.is_regular_file();
  EXPECT_EQ(files, 3);
}
