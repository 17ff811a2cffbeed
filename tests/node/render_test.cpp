// Whole-image properties of the CPU backend.
#include <gtest/gtest.h>

#include <optional>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"
#include "support/orbit_render.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::node;

namespace {

Image renderTiles(const RenderVolume& volume, const Camera& camera, int w, int h,
                  const TransferFunction& tf, const RenderSettings& settings, int threads,
                  const std::vector<Rect>& tiles, std::uint64_t* samples = nullptr) {
  auto backend = makeCpuBackend(threads);
  const auto plan = planFrame(volume, camera, w, h, tf, settings);
  Image full(w, h), tile;
  std::uint64_t total = 0;
  for (auto& r : tiles) {
    total += backend->render(volume, plan, r, tile).samples;
    full.paste(tile, r);
  }
  if (samples) *samples = total;
  return full;
}

Image render(const RenderVolume& volume, const Camera& camera, int w, int h,
             const TransferFunction& tf, const RenderSettings& settings = {}, int threads = 2,
             std::uint64_t* samples = nullptr) {
  return renderTiles(volume, camera, w, h, tf, settings, threads, {{0, 0, w, h}}, samples);
}

const RenderVolume& phantom() {
  static const RenderVolume v = RenderVolume::fromVolume(codec::generateSheppLogan(48), 8);
  return v;
}

TransferFunction phantomTf() { return TransferFunction::preset("ct-soft").rescaled(0, 255); }

Camera threeQuarter() {
  Orbit o;
  o.azimuthDeg = 35, o.elevationDeg = 25;
  return orbitCamera(o, boundingRadius(phantom().info()));
}

std::vector<Rect> grid(int w, int h, int tx, int ty) {
  std::vector<Rect> tiles;
  for (int j = 0; j < ty; ++j)
    for (int i = 0; i < tx; ++i)
      tiles.push_back(
          {w * i / tx, h * j / ty, w * (i + 1) / tx - w * i / tx, h * (j + 1) / ty - h * j / ty});
  return tiles;
}

int opaquePixels(const Image& img) {
  int n = 0;
  for (auto p : img.pixels) n += (p >> 24) > 0;
  return n;
}

}  // namespace

TEST(Render, ThePhantomIsVisible) {
  const Image img = render(phantom(), threeQuarter(), 64, 48, phantomTf());
  EXPECT_GT(opaquePixels(img), 64 * 48 / 5);
  EXPECT_EQ(img.at(0, 0) >> 24, 0u);  // the corner misses the head
}

TEST(Render, AMirrorSymmetricVolumeRendersAMirrorSymmetricImage) {
  // Symmetric under x -> -x only; the camera looks along +y with +x to the right.
  codec::Volume v = codec::Volume::allocate({31, 24, 20}, codec::ScalarType::UInt8);
  for (int z = 0; z < 20; ++z)
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 31; ++x) {
        const double dx = (x - 15) / 12.0, dy = (y - 9) / 10.0, dz = (z - 12) / 6.0;
        const double r = dx * dx + dy * dy + dz * dz + 0.3 * (y / 24.0);
        v.as<std::uint8_t>()[v.index(x, y, z)] = std::uint8_t(r < 1 ? 200 * (1 - r) + 40 : 0);
      }
  v.computeRange();
  const auto volume = RenderVolume::fromVolume(v, 8);
  Orbit o;
  o.azimuthDeg = -90, o.elevationDeg = 0;
  const Camera cam = orbitCamera(o, boundingRadius(volume.info()));
  for (bool shading : {false, true}) {
    RenderSettings s;
    s.shading = shading;
    const Image img =
        render(volume, cam, 64, 40, TransferFunction::preset("hot").rescaled(0, 240), s);
    Image mirrored(img.width, img.height);
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) mirrored.at(x, y) = img.at(img.width - 1 - x, y);
    EXPECT_GT(opaquePixels(img), 200);
    test::expectImagesNear(img, mirrored, 1, 0, shading ? "shaded" : "unshaded");
  }
}

TEST(Render, TilesEqualTheFullRenderPixelForPixel) {
  RenderSettings s;
  s.shading = true;
  const int w = 67, h = 45;  // odd sizes: tiles of unequal width
  const Image full = render(phantom(), threeQuarter(), w, h, phantomTf(), s);
  for (auto [tx, ty] : {std::pair{2, 2}, std::pair{3, 2}, std::pair{1, 5}}) {
    const Image tiled =
        renderTiles(phantom(), threeQuarter(), w, h, phantomTf(), s, 2, grid(w, h, tx, ty));
    EXPECT_EQ(tiled.pixels, full.pixels) << tx << "x" << ty << " tiles";
  }
}

TEST(Render, CpuOutputDoesNotDependOnThreadCount) {
  RenderSettings s;
  s.shading = true;
  const Image one = render(phantom(), threeQuarter(), 50, 40, phantomTf(), s, 1);
  for (int threads : {2, 3, 8}) {
    const Image many = render(phantom(), threeQuarter(), 50, 40, phantomTf(), s, threads);
    EXPECT_EQ(many.pixels, one.pixels) << threads << " threads";
  }
}

TEST(Render, EmptySpaceSkippingChangesNothingButTheWork) {
  // A TF that hides everything below 60% of the range leaves many cells empty.
  TransferFunction tf;
  tf.colors = {{0, 1, 1, 1}, {255, 1, 0.8, 0.6}};
  tf.opacities = {{0, 0}, {150, 0}, {255, 0.6}};
  RenderSettings off;
  off.emptySpaceSkipping = false;
  std::uint64_t samplesOff = 0;
  const Image reference = render(phantom(), threeQuarter(), 64, 48, tf, off, 2, &samplesOff);
  EXPECT_GT(opaquePixels(reference), 100);
  // Every coarse/fine split gives the same pixels with less work.
  for (int factor : {1, 2, 4}) {
    RenderSettings on;
    on.coarseCellFactor = factor;
    std::uint64_t samplesOn = 0;
    const Image a = render(phantom(), threeQuarter(), 64, 48, tf, on, 2, &samplesOn);
    test::expectImagesNear(reference, a, 0, 0, "factor " + std::to_string(factor));
    // The phantom's skull reaches into many cells, so only part of the samples go.
    EXPECT_LT(double(samplesOn), 0.75 * double(samplesOff)) << "factor " << factor;
  }
  const auto plan = planFrame(phantom(), threeQuarter(), 64, 48, tf, {});
  EXPECT_GT(plan.fineEmptyFraction, 0.3);
  EXPECT_LE(plan.emptyFraction, plan.fineEmptyFraction);
}

TEST(Render, AVwzFileRendersLikeTheVolumeItCameFrom) {
  test::TempDir dir;
  const codec::Volume v = codec::generateMarschnerLobb(40);
  voxwall::Progress quiet;
  codec::writeContainer(codec::rawbricks::encode(v, {16}, quiet), dir.path("ml.vwz"));
  const auto fromFile = RenderVolume::open(dir.path("ml.vwz"));
  const auto fromMemory = RenderVolume::fromVolume(v, 8);  // other brick size, same voxels
  Orbit o;
  const Camera cam = orbitCamera(o, boundingRadius(fromFile.info()));
  const auto tf = TransferFunction::preset("cool-warm").rescaled(0, 255);
  RenderSettings s;
  s.shading = true;
  test::expectImagesNear(render(fromMemory, cam, 48, 48, tf, s),
                         render(fromFile, cam, 48, 48, tf, s), 0);
}

TEST(Render, ACameraInsideTheVolumeStillRenders) {
  Orbit o;
  o.distance = 0.2;  // inside the bounding sphere
  const Camera cam = orbitCamera(o, boundingRadius(phantom().info()));
  const Image img = render(phantom(), cam, 32, 32, phantomTf());
  EXPECT_GT(opaquePixels(img), 0);
}

TEST(Render, ATransferFunctionOutsideTheDataShowsNothing) {
  TransferFunction tf;
  tf.colors = {{1000, 1, 1, 1}, {2000, 1, 1, 1}};
  tf.opacities = {{1000, 0}, {1001, 1}, {2000, 1}};
  std::uint64_t samples = 1;
  const Image img = render(phantom(), threeQuarter(), 32, 32, tf, {}, 2, &samples);
  EXPECT_EQ(opaquePixels(img), 0);
  EXPECT_EQ(samples, 0u);  // every cell skipped
}

// A plan that reuses another frame's transfer-function part renders exactly like a fresh one.
TEST(Render, AReusedPlanRendersLikeAFreshOne) {
  const auto volume = RenderVolume::fromVolume(codec::generateSheppLogan(40), 8);
  const auto tf = TransferFunction::preset("mri").rescaled(0, 255);
  RenderSettings settings;
  settings.shading = true;
  const double radius = boundingRadius(volume.info());
  Orbit first, second;
  second.azimuthDeg = 75, second.elevationDeg = -10;
  const auto old = planFrame(volume, orbitCamera(first, radius), 48, 32, tf, settings);
  auto reused = planFrame(volume, orbitCamera(second, radius), 48, 32, tf, settings, &old);
  const auto fresh = planFrame(volume, orbitCamera(second, radius), 48, 32, tf, settings);
  EXPECT_EQ(reused.skip.empty, old.skip.empty);  // the old plan's grids, shared, not copied
  EXPECT_EQ(reused.skip.fineEmpty, old.skip.fineEmpty);
  ASSERT_TRUE(reused.emptyCells && fresh.emptyCells && reused.fineEmptyBits && fresh.fineEmptyBits);
  EXPECT_EQ(*reused.emptyCells, *fresh.emptyCells);
  EXPECT_EQ(*reused.fineEmptyBits, *fresh.fineEmptyBits);
  Image a, b;
  auto backend = makeCpuBackend(1);
  backend->render(volume, reused, {0, 0, 48, 32}, a);
  backend->render(volume, fresh, {0, 0, 48, 32}, b);
  EXPECT_EQ(a.pixels, b.pixels);
  EXPECT_GT(fresh.emptyFraction, 0.0);
}

// An open volume keeps its value ranges packed, and the fine skip grid made from them on every
// core, chunk by chunk, is the one the codec's unpacked ranges give cell by cell: for uint8 data,
// whose cells read a table of every (low, high) pair's answer, and for uint16, asked per cell.
TEST(Render, PackedRangesGiveTheFineSkipGridOfTheUnpackedOnes) {
  for (const codec::ScalarType type : {codec::ScalarType::UInt8, codec::ScalarType::UInt16}) {
    SCOPED_TRACE(std::string(codec::scalarName(type)));
    const auto volume = RenderVolume::fromVolume(codec::generateSheppLogan(180, type));
    ASSERT_TRUE(volume.ranges().packed());
    const codec::RangeGrid unpacked = volume.payload().rangeGrid();
    ASSERT_EQ(unpacked.type(), type);
    ASSERT_GT(unpacked.cellCount(), codec::RangeGrid::kChunkCells);  // more than one chunk
    EXPECT_LT(volume.ranges().bytes(), unpacked.bytes());
    const auto tf =
        TransferFunction::preset("mri").rescaled(volume.info().valueMin, volume.info().valueMax);
    const auto plan = planFrame(volume, orbitCamera(Orbit{}, boundingRadius(volume.info())), 48, 32,
                                tf, RenderSettings{});
    ASSERT_TRUE(plan.fineEmptyBits);
    std::vector<std::uint32_t> want((unpacked.cellCount() + 31) / 32, 0u);
    unpacked.forEach([&](std::size_t c, float a, float b) {
      if (plan.lut.maxOpacity(a, b) <= 0.0f) want[c >> 5] |= 1u << (c & 31);
    });
    EXPECT_EQ(*plan.fineEmptyBits, want);
    EXPECT_GT(plan.fineEmptyFraction, 0.0);
    EXPECT_LT(plan.fineEmptyFraction, 1.0);
  }
}

// What a CUDA backend samples with DeviceDecode::Whole: every codec's volume decoded by its codec
// and bricked raw renders as its compressed view does (the views sample exactly the decoded
// values), and decodedBytes() is the size of those bricks. Raw volumes, series and --lod have none.
TEST(RenderVolume, TheVolumeDecodedWholeRendersLikeItsCompressedView) {
  const auto tf = TransferFunction::preset("ct-soft");
  int decoded = 0;
  for (const codec::Codec* c : codec::codecs())
    for (codec::CodecSample& sample : c->samples()) {
      SCOPED_TRACE(sample.name);
      const codec::CompressedVolume file = sample.volume;
      std::optional<RenderVolume> volume;
      try {
        volume = RenderVolume::fromCompressed(std::move(sample.volume));
      } catch (const FormatError&) {
        continue;  // a file the codec holds but cannot render (RGBA svmm)
      }
      const codec::Volume voxels = c->decode(file.info, file.view());
      const codec::RenderPayload* whole = volume->decodedPayload();
      if (volume->info().codec == codec::rawbricks::kCodecId) {
        EXPECT_EQ(whole, nullptr);
        EXPECT_EQ(volume->decodedBytes(), 0u);
        continue;
      }
      ASSERT_NE(whole, nullptr);
      EXPECT_EQ(volume->decodedBytes(), whole->bytes().size());
      EXPECT_NE(volume->decodedPayloadId(), volume->payloadId());
      const auto reference = RenderVolume::fromVolume(voxels);
      const auto rescaled = tf.rescaled(volume->info().valueMin, volume->info().valueMax);
      for (bool shading : {false, true})
        test::expectImagesNear(test::renderOrbit(reference, 48, 40, rescaled, shading),
                               test::renderOrbit(*volume, 48, 40, rescaled, shading), 1, 60,
                               sample.name + (shading ? " shaded" : ""));
      ++decoded;
    }
  EXPECT_GE(decoded, int(codec::codecs().size()) - 1);
}
