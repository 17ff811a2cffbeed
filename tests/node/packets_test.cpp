// The CPU's SIMD ray packets against its one-ray-at-a-time path (the per-ray code CUDA runs), for
// every view type the raycaster is compiled for: the same picture within a rounding step, shaded
// and unshaded, with and without skipping, on tiles whose edges cut packets.
#include <gtest/gtest.h>

#include <set>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::node;

namespace {

struct Case {
  std::string name;
  RenderVolume volume;
  TransferFunction tf;
  bool sample = false;  // a registered codec's sample file: small, of no size the checks assume
};

// Shepp-Logan's values as uint16 (x 257) and as int16 (- 100).
std::pair<codec::Volume, codec::Volume> wideAndSigned(const codec::Volume& sl) {
  codec::Volume wide = codec::Volume::allocate(sl.dims, codec::ScalarType::UInt16);
  codec::Volume signedV = codec::Volume::allocate(sl.dims, codec::ScalarType::Int16);
  for (std::size_t i = 0; i < sl.as<std::uint8_t>().size(); ++i) {
    wide.as<std::uint16_t>()[i] = std::uint16_t(sl.as<std::uint8_t>()[i] * 257);
    signedV.as<std::int16_t>()[i] = std::int16_t(int(sl.as<std::uint8_t>()[i]) - 100);
  }
  wide.computeRange(), signedV.computeRange();
  return {std::move(wide), std::move(signedV)};
}

// Every sample file of every registered codec that can be rendered (a codec added to the registry
// is covered with no edit here): small volumes, of every view type the codec has.
void addCodecSamples(std::vector<Case>& cases) {
  for (const codec::Codec* c : codec::codecs())
    for (codec::CodecSample& sample : c->samples()) {
      try {
        auto volume = RenderVolume::fromCompressed(std::move(sample.volume));
        const auto tf = TransferFunction::preset("ct-soft").rescaled(volume.info().valueMin,
                                                                     volume.info().valueMax);
        cases.push_back({sample.name, std::move(volume), tf, true});
      } catch (const FormatError&) {
        // a file the codec holds but cannot render (RGBA svmm)
      }
    }
}

// One volume of a size the checks below rely on per view type of the raycaster (codec::AnyView),
// then every codec's samples.
std::vector<Case> everyView(const test::TempDir& dir) {
  std::vector<Case> cases;
  const auto ct = TransferFunction::preset("ct-soft").rescaled(0, 255);
  const auto unit = TransferFunction::preset("cool-warm").rescaled(0, 1);
  const auto signedTf = TransferFunction::preset("ct-soft").rescaled(-100, 155);
  voxwall::Progress quiet;
  // Odd sizes: cells straddle brick borders and the padded edge.
  const codec::Volume sl = codec::generateSheppLogan(45);
  cases.push_back({"raw uint8", RenderVolume::fromVolume(sl, 16), ct});
  const auto [wide, signedV] = wideAndSigned(sl);
  cases.push_back({"raw uint16", RenderVolume::fromVolume(wide, 8), ct.rescaled(0, 65535)});
  cases.push_back({"raw int16", RenderVolume::fromVolume(signedV, 8), signedTf});
  const codec::Volume ml = codec::generateMarschnerLobb(37, codec::ScalarType::Float32);
  cases.push_back({"raw float32", RenderVolume::fromVolume(ml, 16), unit});
  auto file = [&](const std::string& name, const codec::CompressedVolume& c) {
    codec::writeContainer(c, dir.path(name));
    return RenderVolume::open(dir.path(name));
  };
  cases.push_back({"vq", file("vq.vwz", codec::vq::encode(sl, {}, quiet)), ct});
  cases.push_back({"svmm", file("svmm.vwz", codec::svmm::encode(sl, {}, quiet)), ct});
  for (int side : {4, 6, 8}) {
    const std::string tag = std::to_string(side);  // (GCC 12 warns on "k" + to_string())
    codec::ksvd::Params p;
    p.blockSide = side, p.atoms = 48, p.sparsity = 5, p.iterations = 3;
    cases.push_back(
        {"ksvd " + tag, file("k" + tag + ".vwz", codec::ksvd::encode(ml, p, quiet)), unit});
  }
  codec::tvq::Params tp;
  tp.codeBits = 10, tp.iterations = 3, tp.subvolumeVoxels = 24;
  cases.push_back({"tvq", file("tvq.vwz", codec::tvq::encode(sl, tp, quiet)), ct});
  addCodecSamples(cases);
  return cases;
}

Image render(const Case& c, const RenderSettings& s, bool packets, const Rect& tile,
             std::uint64_t decodeCacheBytes = kDefaultDecodeCacheBytes,
             DecodeCacheUse* use = nullptr) {
  Orbit o;
  o.azimuthDeg = 35, o.elevationDeg = 25;
  const Camera camera = orbitCamera(o, boundingRadius(c.volume.info()));
  const auto plan = planFrame(c.volume, camera, 96, 72, c.tf, s);
  Image out;
  const auto backend = makeCpuBackend(2, packets, decodeCacheBytes);
  backend->render(c.volume, plan, tile, out);
  if (use) *use = cpuDecodeCacheUse(*backend);
  return out;
}

// The codecs whose full-resolution voxels the packets sample from decoded pages.
bool paged(const Case& c) { return !c.name.starts_with("raw"); }

}  // namespace

TEST(Packets, SameImageAsOneRayAtATimeForEveryView) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "this CPU has no SIMD target the build compiled";
  EXPECT_NE(makeCpuBackend(1, true)->name().find("packets"), std::string::npos);
  EXPECT_NE(makeCpuBackend(1, false)->name().find("one ray at a time"), std::string::npos);
  test::TempDir dir;
  const auto cases = everyView(dir);
  std::set<std::size_t> views;
  for (const auto& c : cases) views.insert(c.volume.view().index());
  EXPECT_EQ(views.size(), std::variant_size_v<ViewVariant>)
      << "a view type has neither a case here nor a sample of its codec";
  // The whole screen, and a tile whose size and origin are no multiple of a packet's 4 x 4.
  const Rect tiles[] = {{0, 0, 96, 72}, {13, 7, 37, 23}};
  for (const auto& c : cases)
    for (bool shading : {false, true})
      for (bool skipping : {true, false})
        for (const Rect& tile : tiles) {
          RenderSettings s;
          s.shading = shading, s.emptySpaceSkipping = skipping;
          const std::string label = c.name + (shading ? " shaded" : "") +
                                    (skipping ? "" : " no skipping") + " tile " +
                                    std::to_string(tile.width) + "x" + std::to_string(tile.height);
          const Image scalar = render(c, s, false, tile);
          const Image packets = render(c, s, true, tile);
          // Not a blank picture compared with another.
          if (tile.width == 96 && !c.sample) {
            std::size_t lit = 0;
            for (auto p : scalar.pixels) lit += (p >> 24) > 8;
            EXPECT_GT(lit, scalar.pixels.size() / 10) << label;
          }
          test::expectImagesNear(scalar, packets, 1, 60.0, label);
        }
}

// Every SIMD target the build compiled and this CPU runs (a portable build has AVX2 and AVX-512
// on x86; a -march=native build the machine's own) gives the picture of one ray at a time: the
// per-ray code is compiled for each target, and each target's packets are its own.
TEST(Packets, EverySimdTargetGivesTheSamePicture) {
  const auto targets = cpuPacketTargets();
  ASSERT_FALSE(targets.empty());
  EXPECT_THROW(restrictCpuPacketTarget("no such target"), std::invalid_argument);
  test::TempDir dir;
  const auto cases = everyView(dir);
  RenderSettings s;
  s.shading = true;
  const Rect tile{13, 7, 61, 47};
  std::vector<Image> scalar;
  for (const auto& c : cases) scalar.push_back(render(c, s, false, tile));
  std::size_t lastLanes = 0;
  int simd = 0;
  for (const auto& target : targets) {
    restrictCpuPacketTarget(target);
    const std::size_t lanes = cpuPacketLanes();
    const auto name = makeCpuBackend(1, true)->name();
    if (lanes > 1) {
      ++simd;
      EXPECT_NE(name.find(target + " packets of " + std::to_string(lanes)), std::string::npos)
          << name;
      // Best first: each next target has narrower vectors (x86: AVX-512 16 lanes, AVX2 8).
      if (lastLanes > 0) {
        EXPECT_LT(lanes, lastLanes) << target;
      }
      lastLanes = lanes;
    } else {
      EXPECT_NE(name.find("one ray at a time"), std::string::npos) << target << ": " << name;
    }
    for (std::size_t i = 0; i < cases.size(); ++i)
      test::expectImagesNear(scalar[i], render(cases[i], s, true, tile), 1, 60.0,
                             cases[i].name + " on " + target);
  }
  restrictCpuPacketTarget("");
  EXPECT_EQ(cpuPacketTargets(), targets);
  std::printf("SIMD targets: %d with packets of %zu targets in all\n", simd, targets.size());
}

// The six-sample gradients and svmm's nearest sampling and levels of detail take the views'
// per-lane hooks: the same picture too.
TEST(Packets, SixSampleGradientsAndSvmmTraversalMatch) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "this CPU has no SIMD target the build compiled";
  test::TempDir dir;
  for (const auto& c : everyView(dir)) {
    RenderSettings s;
    s.shading = true, s.cellGradients = false;
    test::expectImagesNear(render(c, s, false, {0, 0, 96, 72}), render(c, s, true, {0, 0, 96, 72}),
                           1, 60.0, c.name + " six samples");
    if (!c.volume.traversal()) continue;
    for (bool nearest : {true, false}) {
      RenderSettings t;
      t.nearest = nearest, t.levelOfDetail = true, t.shading = true;
      test::expectImagesNear(render(c, t, false, {0, 0, 96, 72}),
                             render(c, t, true, {0, 0, 96, 72}), 1, 60.0,
                             c.name + (nearest ? " nearest" : "") + " level of detail");
    }
  }
}

// Compressed volumes (vq, svmm, ksvd, tvq) are sampled by the packets from decoded pages: the same
// picture as the bricks decoded per ray, with room for every page, for one page only (the others
// evicted and decoded again as rays come back to them), with none and with a budget under one
// page.
TEST(Packets, DecodedPagesGiveTheSamePictureWhateverTheirRoom) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "this CPU has no SIMD target the build compiled";
  test::TempDir dir;
  int pagedCases = 0;
  for (const auto& c : everyView(dir)) {
    for (bool shading : {false, true}) {
      RenderSettings s;
      s.shading = shading;
      const Image scalar = render(c, s, false, {0, 0, 96, 72});
      DecodeCacheUse all, one, none;
      const Image roomy = render(c, s, true, {0, 0, 96, 72}, kDefaultDecodeCacheBytes, &all);
      const std::string label = c.name + (shading ? " shaded" : "");
      test::expectImagesNear(scalar, roomy, 1, 60.0, label + ", every page");
      if (!paged(c)) {
        EXPECT_EQ(all.bytes, 0u) << label;
        continue;
      }
      if (!c.sample) {
        ++pagedCases;
        // A 45^3 or 37^3 volume is eight pages of 32^3; the rays reach every one, once each.
        EXPECT_EQ(all.allPagesBytes, all.bytes) << label;
        EXPECT_EQ(all.pageBytes * 8, all.bytes) << label;
        EXPECT_EQ(all.misses + all.scratch, 8u) << label;
        EXPECT_EQ(all.evictions, 0u) << label;
        EXPECT_GT(all.hits, 0u) << label;
        // uint8 data (vq, svmm, tvq) is paged a byte a voxel; float32 (ksvd) in floats.
        EXPECT_EQ(all.pageBytes, std::uint64_t(35 * 35 * 35) * (c.name.starts_with("ksvd") ? 4 : 1))
            << label;
      }
      const std::uint64_t page = all.pageBytes;
      test::expectImagesNear(scalar, render(c, s, true, {0, 0, 96, 72}, page, &one), 1, 60.0,
                             label + ", one page");
      // (The page may be evicted at the end, its slot waiting for the threads to move on.)
      EXPECT_LE(one.bytes, page) << label;
      EXPECT_GT(one.misses, 0u) << label;
      EXPECT_EQ(one.capacityBytes, page) << label;
      test::expectImagesNear(scalar, render(c, s, true, {0, 0, 96, 72}, 0, &none), 1, 60.0,
                             label + ", no pages");
      EXPECT_EQ(none.bytes, 0u) << label;
      // A budget under one page holds none.
      DecodeCacheUse tiny;
      test::expectImagesNear(scalar, render(c, s, true, {0, 0, 96, 72}, page - 1, &tiny), 1, 60.0,
                             label + ", less than a page");
      EXPECT_EQ(tiny.capacityBytes, 0u) << label;
    }
  }
  EXPECT_EQ(pagedCases, 2 * 6) << "vq, svmm, three ksvd, tvq";
}

// Eviction: a budget of two or three pages gives exactly the picture of room for every page, for
// every paged codec and every scalar type a page stores (uint8, 16-bit with and without a bias,
// float32), shaded and not, on every SIMD target, with threads evicting each other's pages.
TEST(Packets, EvictingPagesGiveExactlyThePictureOfUnlimitedRoom) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "this CPU has no SIMD target the build compiled";
  test::TempDir dir;
  auto cases = everyView(dir);
  std::erase_if(cases, [](const Case& c) { return !paged(c) || c.sample; });
  {
    voxwall::Progress quiet;
    const codec::Volume sl = codec::generateSheppLogan(45);
    const auto [wide, signedV] = wideAndSigned(sl);
    auto file = [&](const std::string& name, const codec::CompressedVolume& c) {
      codec::writeContainer(c, dir.path(name));
      return RenderVolume::open(dir.path(name));
    };
    const auto ct = TransferFunction::preset("ct-soft").rescaled(0, 255);
    cases.push_back({"vq int16", file("vq16.vwz", codec::vq::encode(signedV, {}, quiet)),
                     TransferFunction::preset("ct-soft").rescaled(-100, 155)});
    cases.push_back({"svmm uint16", file("svmm16.vwz", codec::svmm::encode(wide, {}, quiet)),
                     ct.rescaled(0, 65535)});
    codec::ksvd::Params p;
    p.blockSide = 4, p.atoms = 48, p.sparsity = 5, p.iterations = 3;
    cases.push_back({"ksvd uint8", file("k8.vwz", codec::ksvd::encode(sl, p, quiet)), ct});
  }
  const auto targets = cpuPacketTargets();
  int checked = 0;
  for (const auto& target : targets) {
    restrictCpuPacketTarget(target);
    if (cpuPacketLanes() <= 1) continue;
    for (const auto& c : cases)
      for (bool shading : {false, true}) {
        RenderSettings s;
        s.shading = shading;
        const std::string label = c.name + (shading ? " shaded" : "") + " on " + target;
        DecodeCacheUse all;
        const Image unlimited = render(c, s, true, {0, 0, 96, 72}, std::uint64_t(1) << 40, &all);
        ASSERT_GT(all.pageBytes, 0u) << label;
        for (int pages : {2, 3}) {
          DecodeCacheUse few;
          const Image evicting =
              render(c, s, true, {0, 0, 96, 72}, std::uint64_t(pages) * all.pageBytes, &few);
          test::expectImagesNear(unlimited, evicting, 0, 0.0,
                                 label + ", " + std::to_string(pages) + " pages");
          EXPECT_EQ(few.capacityBytes, std::uint64_t(pages) * all.pageBytes) << label;
          EXPECT_LE(few.bytes, few.capacityBytes) << label;
          // The eight pages do not fit: some were evicted and decoded again.
          EXPECT_GT(few.evictions, 0u) << label;
          EXPECT_GT(few.misses + few.scratch, 8u) << label;
          ++checked;
        }
      }
  }
  restrictCpuPacketTarget("");
  EXPECT_GT(checked, 0);
}

// A rank decodes only the pages its own rectangles' rays reach: the left half of the screen (a
// strip of a two-rank cut) touches fewer pages than the whole screen, and its other half the rest.
TEST(Packets, AStripDecodesOnlyThePagesItsRaysReach) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "this CPU has no SIMD target the build compiled";
  voxwall::Progress quiet;
  test::TempDir dir;
  // 128^3: 64 pages; the camera looks down an axis so a half-screen strip sees about half of them.
  const codec::Volume sl = codec::generateSheppLogan(128);
  codec::writeContainer(codec::vq::encode(sl, {}, quiet), dir.path("vq.vwz"));
  const Case c{"vq", RenderVolume::open(dir.path("vq.vwz")),
               TransferFunction::preset("ct-soft").rescaled(0, 255)};
  Orbit o;
  o.azimuthDeg = 0, o.elevationDeg = 0;
  const Camera camera = orbitCamera(o, boundingRadius(c.volume.info()));
  RenderSettings s;
  const auto plan = planFrame(c.volume, camera, 128, 96, c.tf, s);
  auto decoded = [&](const Rect& tile) {
    const auto backend = makeCpuBackend(2, true, std::uint64_t(1) << 40);
    Image out;
    const TileStats stats = backend->render(c.volume, plan, tile, out);
    const DecodeCacheUse use = cpuDecodeCacheUse(*backend);
    EXPECT_EQ(stats.pageDecoded, use.misses + use.scratch);
    EXPECT_EQ(use.evictions, 0u);
    return use.misses + use.scratch;
  };
  const std::uint64_t whole = decoded({0, 0, 128, 96});
  const std::uint64_t left = decoded({0, 0, 64, 96}), right = decoded({64, 0, 64, 96});
  EXPECT_GT(whole, 0u);
  EXPECT_LT(left, whole);
  EXPECT_LT(right, whole);
  EXPECT_GE(left + right, whole);
  std::printf("pages decoded: whole screen %llu, left strip %llu, right strip %llu\n",
              (unsigned long long)whole, (unsigned long long)left, (unsigned long long)right);
}

// Levels of detail on ksvd and svmm: lanes whose footprint picks a coarser level leave the pages
// for the view's own levels, in the same packet as lanes still on the full-resolution pages. Small
// screens make wide footprints: at 32 x 24 the near side of the volume samples level 0, the far
// side 1.
TEST(Packets, DecodedPagesWithLevelsOfDetail) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "this CPU has no SIMD target the build compiled";
  test::TempDir dir;
  int cases = 0;
  for (const auto& c : everyView(dir)) {
    if (!c.volume.traversal()) continue;
    cases += !c.sample;
    for (int height : {12, 24, 36}) {
      RenderSettings s;
      s.levelOfDetail = true, s.shading = true;
      Orbit o;
      o.azimuthDeg = 35, o.elevationDeg = 25;
      const Camera camera = orbitCamera(o, boundingRadius(c.volume.info()));
      const int width = height * 4 / 3;
      const auto plan = planFrame(c.volume, camera, width, height, c.tf, s);
      Image scalar, packets;
      makeCpuBackend(1, false)->render(c.volume, plan, {0, 0, width, height}, scalar);
      const auto backend = makeCpuBackend(1, true);
      backend->render(c.volume, plan, {0, 0, width, height}, packets);
      const std::string label = c.name + " level of detail at " + std::to_string(height);
      test::expectImagesNear(scalar, packets, 1, 60.0, label);
      if (height == 36 && !c.sample) {
        EXPECT_GT(cpuDecodeCacheUse(*backend).bytes, 0u) << label;
      }
    }
  }
  EXPECT_EQ(cases, 4) << "svmm, three ksvd";
}

// Lod under pressure (svmm, ksvd): with room for every page nothing changes; with a pool another
// view filled, a frame samples the next coarser level where its pages are not resident (close
// to the full-resolution picture, counted), decodes those pages after the frame (a quarter of the
// pool at a time, evicting the other view's) and sharpens frame by frame until it is exactly the
// picture of unlimited room.
TEST(Packets, LodUnderPressureSamplesCoarserLevelsThenSharpens) {
  if (cpuPacketLanes() <= 1) GTEST_SKIP() << "this CPU has no SIMD target the build compiled";
  voxwall::Progress quiet;
  test::TempDir dir;
  // 128^3: 64 pages; the camera looks down an axis, so the halves of the screen reach apart pages.
  const codec::Volume sl = codec::generateSheppLogan(128);
  auto file = [&](const std::string& name, const codec::CompressedVolume& c) {
    codec::writeContainer(c, dir.path(name));
    return RenderVolume::open(dir.path(name));
  };
  codec::ksvd::Params kp;
  kp.blockSide = 4, kp.atoms = 48, kp.sparsity = 5, kp.iterations = 3;
  const auto ct = TransferFunction::preset("ct-soft").rescaled(0, 255);
  std::vector<Case> cases;
  cases.push_back({"svmm", file("svmm.vwz", codec::svmm::encode(sl, {}, quiet)), ct});
  cases.push_back({"ksvd", file("ksvd.vwz", codec::ksvd::encode(sl, kp, quiet)), ct});
  Orbit o;
  o.azimuthDeg = 0, o.elevationDeg = 0;
  const Rect left{0, 0, 64, 96}, right{64, 0, 64, 96};
  for (const auto& c : cases)
    for (bool shading : {false, true}) {
      const std::string label = c.name + (shading ? " shaded" : "");
      const Camera camera = orbitCamera(o, boundingRadius(c.volume.info()));
      RenderSettings s;
      s.shading = shading;
      const auto plain = planFrame(c.volume, camera, 128, 96, c.tf, s);
      s.lodUnderPressure = true;
      const auto pressed = planFrame(c.volume, camera, 128, 96, c.tf, s);
      Image full, image;
      const auto unlimited = makeCpuBackend(2, true, std::uint64_t(1) << 40);
      unlimited->render(c.volume, plain, right, full);
      const std::uint64_t pageBytes = cpuDecodeCacheUse(*unlimited).pageBytes;
      const std::uint64_t rightPages = cpuDecodeCacheUse(*unlimited).bytes / pageBytes;
      ASSERT_GT(pageBytes, 0u) << label;
      // With room for every page nothing is sampled coarser: the same picture.
      {
        const auto roomy = makeCpuBackend(2, true, std::uint64_t(1) << 40);
        const TileStats stats = roomy->render(c.volume, pressed, right, image);
        test::expectImagesNear(full, image, 0, 0.0, label + ", room for every page");
        EXPECT_EQ(stats.pageCoarse, 0u) << label;
      }
      // Room for the right half's pages, filled by the left half's; then the right half, frame
      // after frame.
      const std::uint64_t room = rightPages * pageBytes;
      const auto backend = makeCpuBackend(2, true, room);
      backend->render(c.volume, pressed, left, image);
      ASSERT_EQ(cpuDecodeCacheUse(*backend).bytes, room) << label;
      std::vector<std::uint64_t> coarse;
      for (int frame = 0; frame < 12; ++frame) {
        const TileStats stats = backend->render(c.volume, pressed, right, image);
        coarse.push_back(stats.pageCoarse);
        EXPECT_LE(stats.pageCoarse, stats.pageMissed) << label;
        EXPECT_LE(cpuDecodeCacheUse(*backend).bytes, room) << label;
        if (frame == 0) {
          EXPECT_GT(stats.pageCoarse, 0u) << label;
          EXPECT_GT(stats.pageDecoded, 0u) << label << ": decoded after the frame";
          EXPECT_GT(stats.pageEvictions, 0u) << label << ": the left half's pages";
          // Level 1 is twice as coarse for ksvd, four times for svmm (its blocks of 4).
          test::expectImagesNear(full, image, 255, c.name == "ksvd" ? 20.0 : 12.0,
                                 label + ", first frame under pressure");
          EXPECT_GT(cpuDecodeCacheUse(*backend).coarseBytes, 0u) << label << ": level 1's pages";
        }
        if (stats.pageCoarse == 0) break;
      }
      ASSERT_EQ(coarse.back(), 0u) << label << ": never sharpened";
      EXPECT_GT(coarse.size(), 2u) << label << ": a quarter of the pool a frame";
      test::expectImagesNear(full, image, 0, 0.0, label + ", sharpened");
      std::string counts;
      for (auto n : coarse) counts += ' ' + std::to_string(n);
      std::printf("%s: samples from coarser levels, frame by frame:%s\n", label.c_str(),
                  counts.c_str());
    }
}
