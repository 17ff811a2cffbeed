// Rendering the svmm codec's view (with its traversal: constant regions skipped in one step,
// nearest and level-of-detail sampling) against the raw codec's.
#include <gtest/gtest.h>

#include <cstdio>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::node;

namespace {

struct Rendered {
  Image image;
  std::uint64_t samples = 0;
};

Rendered render(const RenderVolume& volume, int w, int h, const TransferFunction& tf,
                RenderSettings s, int threads = 2, const std::vector<Rect>& tiles = {}) {
  Orbit o;
  o.azimuthDeg = 35, o.elevationDeg = 25;
  const Camera camera = orbitCamera(o, boundingRadius(volume.info()));
  auto backend = makeCpuBackend(threads);
  const auto plan = planFrame(volume, camera, w, h, tf, s);
  Rendered out{Image(w, h), 0};
  Image tile;
  for (const auto& r : tiles.empty() ? std::vector<Rect>{{0, 0, w, h}} : tiles) {
    out.samples += backend->render(volume, plan, r, tile).samples;
    out.image.paste(tile, r);
  }
  return out;
}

RenderSettings shaded(bool on) {
  RenderSettings s;
  s.shading = on;
  return s;
}

// (GCC 12 warns falsely about "literal" + std::string: -Wrestrict, bug 105329.)
std::string fileName(int w, int r, int q, bool stepped) {
  char name[64];
  std::snprintf(name, sizeof name, "v%d_%d_%d%s.vwz", w, r, q, stepped ? "s" : "");
  return name;
}

RenderVolume svmmFile(const test::TempDir& dir, const codec::Volume& v, int w, int r, int q,
                      bool stepped = false, codec::svmm::EncodeStats* stats = nullptr) {
  voxwall::Progress quiet;
  codec::svmm::Params p;
  p.blockWidth = w, p.rootWidth = r, p.quality = q, p.stepped = stepped;
  const std::string name = fileName(w, r, q, stepped);
  codec::writeContainer(codec::svmm::encode(v, p, quiet, stats), dir.path(name));
  return RenderVolume::open(dir.path(name));
}

codec::Volume twelveBit(const codec::Volume& v8) {
  codec::Volume v = codec::Volume::allocate(v8.dims, codec::ScalarType::UInt16, v8.spacing);
  for (std::size_t i = 0; i < v.voxelCount(); ++i)
    v.as<std::uint16_t>()[i] = std::uint16_t(v8.as<std::uint8_t>()[i] * 16 + (i % 7));
  v.computeRange();
  return v;
}

}  // namespace

// As for vq: samples are bit-identical to the raw view of the same voxels, but -march=native may
// fuse multiply-adds differently in the two instantiations, so pixels may differ by one level.
TEST(SvmmRender, LosslessRendersLikeRaw) {
  test::TempDir dir;
  for (const codec::Volume& v : {codec::generateSheppLogan(45), codec::generateMarschnerLobb(38),
                                 twelveBit(codec::generateSheppLogan(41))}) {
    const auto raw = RenderVolume::fromVolume(v, 8);
    const auto tf = TransferFunction::preset("ct-soft").rescaled(v.valueMin, v.valueMax);
    struct Shape {
      int w, r;
      bool stepped;
    };
    for (const Shape& sh : {Shape{4, 8, false}, Shape{8, 8, false}, Shape{0, 4, true}}) {
      const auto svmm = svmmFile(dir, v, sh.w, sh.r, 100, sh.stepped);
      EXPECT_EQ(svmm.info().codec, codec::svmm::SvmmCodecEntry::kId);
      for (bool shading : {false, true}) {
        char label[64];
        std::snprintf(label, sizeof label, "%s w=%d%s",
                      std::string(codec::scalarName(v.type)).c_str(), sh.w,
                      shading ? " shaded" : "");
        const Rendered reference = render(raw, 72, 56, tf, shaded(shading));
        const Rendered got = render(svmm, 72, 56, tf, shaded(shading));
        test::expectImagesNear(reference.image, got.image, 1, 70, label);
        test::expectImagesNear(reference.image,
                               render(svmm, 72, 56, tf, shaded(shading), 3,
                                      {{0, 0, 40, 30}, {40, 0, 32, 30}, {0, 30, 72, 26}})
                                   .image,
                               1, 70, std::string(label) + " tiles");
        // Transparent terminal blocks are skipped in one step: never more samples than raw.
        EXPECT_LE(got.samples, reference.samples) << label;
      }
    }
  }
}

TEST(SvmmRender, LossyRendersLikeItsDecodedVolume) {
  test::TempDir dir;
  const codec::Volume v = codec::generateMarschnerLobb(48);
  const auto tf = TransferFunction::preset("cool-warm").rescaled(0, 255);
  const Image reference = render(RenderVolume::fromVolume(v), 64, 64, tf, shaded(true)).image;
  double last = std::numeric_limits<double>::infinity();
  for (int q : {100, 90, 80, 65}) {
    codec::svmm::EncodeStats stats;
    const auto svmm = svmmFile(dir, v, 4, 8, q, false, &stats);
    const auto file = codec::ContainerFile::open(dir.path(fileName(4, 8, q, false)));
    const codec::Volume decoded = codec::svmm::decode(file.info(), file.sections());
    const Image image = render(svmm, 64, 64, tf, shaded(true)).image;
    test::expectImagesNear(
        render(RenderVolume::fromVolume(decoded), 64, 64, tf, shaded(true)).image, image, 1, 70,
        std::string("q ") += std::to_string(q));
    const double imagePsnr = voxwall::compareImages(reference, image).psnrDb;
    RecordProperty(std::string("image_psnr_q") += std::to_string(q), std::to_string(imagePsnr));
    std::printf("q %d: volume PSNR %.2f dB, image PSNR %.2f dB\n", q, stats.psnr, imagePsnr);
    if (q == 100) {
      EXPECT_GE(imagePsnr, 50.0);
    }
    EXPECT_LE(imagePsnr, last + 0.5) << "q " << q;
    last = imagePsnr;
  }
}

TEST(SvmmRender, NearestSamplingIsTheSameWhateverTheTree) {
  // Nearest-voxel renders of three trees of the same voxels (one level: nothing to skip; w = 4;
  // stepped) are the same image: region skipping and refinement change only the work.
  test::TempDir dir;
  const codec::Volume v = codec::generateSheppLogan(44);
  const auto tf = TransferFunction::preset("ct-soft").rescaled(0, 255);
  RenderSettings s;
  s.nearest = true;
  const Rendered flat = render(svmmFile(dir, v, 4, 64, 100), 64, 48, tf, s);
  const Rendered tree = render(svmmFile(dir, v, 4, 4, 100), 64, 48, tf, s);
  const Rendered stepped = render(svmmFile(dir, v, 0, 4, 100, true), 64, 48, tf, s);
  test::expectImagesNear(flat.image, tree.image, 1, 70, "w=4");
  test::expectImagesNear(flat.image, stepped.image, 1, 70, "stepped");
  EXPECT_LT(tree.samples, flat.samples);
  // And it is not the trilinear image.
  RenderSettings t;
  EXPECT_GT(
      voxwall::compareImages(render(svmmFile(dir, v, 4, 4, 100), 64, 48, tf, t).image, tree.image)
          .maxAbs,
      5);
}

TEST(SvmmRender, LevelOfDetailUsesCoarseLevelsForSmallImages) {
  // A 16x12 image of a 96^3 volume: a pixel covers about 8 voxels, so w = 2 levels 1..3 are
  // picked; the image stays close to the finest-level one and takes fewer samples than it.
  test::TempDir dir;
  const codec::Volume v = codec::generateMarschnerLobb(96);
  const auto tf = TransferFunction::preset("cool-warm").rescaled(0, 255);
  const auto svmm = svmmFile(dir, v, 2, 4, 100);
  RenderSettings fine, lod;
  lod.levelOfDetail = true;
  const Rendered a = render(svmm, 16, 12, tf, fine);
  const Rendered b = render(svmm, 16, 12, tf, lod);
  const auto cmp = voxwall::compareImages(a.image, b.image);
  EXPECT_GT(cmp.maxAbs, 0);     // coarse levels were used
  EXPECT_GT(cmp.psnrDb, 20.0);  // and they are the same picture
  // At full size the footprint is below one voxel: level 0 only, identical pixels.
  test::expectImagesNear(render(svmm, 200, 150, tf, fine).image,
                         render(svmm, 200, 150, tf, lod).image, 0);
}

TEST(SvmmRender, RgbaVolumesAreRefusedWithOneLine) {
  test::TempDir dir;
  voxwall::Progress quiet;
  codec::writeContainer(codec::svmm::encodeRgba(codec::svmm::generateMengerRgba(2), {}, quiet),
                        dir.path("rgba.vwz"));
  try {
    (void)RenderVolume::open(dir.path("rgba.vwz"));
    ADD_FAILURE() << "an RGBA svmm volume was accepted for rendering";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("RGBA"), std::string::npos) << e.what();
  }
}
