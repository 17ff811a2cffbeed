// The tvq codec (Fout & Ma): transforms, classification, associated codebooks, progressive
// levels, rates and malformed files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/host_tables.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/core/errors.hpp>

#include "support/sections.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using namespace voxwall::codec::tvq;

namespace {

Params quickTvq() {
  Params p;
  p.codeBits = 12, p.iterations = 4, p.subvolumeVoxels = 32;
  return p;
}

CompressedVolume encodeQuiet(const Volume& v, const Params& p, EncodeStats* s = nullptr) {
  Progress quiet;
  return tvq::encode(v, p, quiet, s);
}

void expectOrthonormal(const Basis& b, const char* label) {
  double worst = 0;
  for (int i = 0; i < kBlockVoxels; ++i)
    for (int j = 0; j < kBlockVoxels; ++j) {
      double dot = 0;
      for (int v = 0; v < kBlockVoxels; ++v) dot += double(b.row(i)[v]) * double(b.row(j)[v]);
      worst = std::max(worst, std::abs(dot - (i == j ? 1.0 : 0.0)));
    }
  EXPECT_LT(worst, 1e-5) << label;
  for (int v = 0; v < kBlockVoxels; ++v) EXPECT_FLOAT_EQ(b.row(0)[v], 0.125f) << label;
  std::array<int, 8> sizes{};
  for (int k = 0; k < kBlockVoxels; ++k) ++sizes[b.zone[std::size_t(k)]];
  for (int z = 0; z < 8; ++z) EXPECT_EQ(sizes[std::size_t(z)], 8) << label << " zone " << z;
  EXPECT_EQ(b.zone[0], 0) << label;
}

Basis kltOf(const Volume& v) {
  Progress quiet;
  const glm::ivec3 blocks = (v.dims + 3) / 4;
  const std::uint64_t n = std::uint64_t(blocks.x) * blocks.y * blocks.z;
  return kltBasis(
      n,
      [&](std::uint64_t i, float* out) {
        const int bx = int(i % blocks.x), by = int(i / blocks.x % blocks.y),
                  bz = int(i / (std::uint64_t(blocks.x) * blocks.y));
        for (int z = 0, j = 0; z < 4; ++z)
          for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x, ++j)
              out[j] = float(v.valueAt(v.index(std::min(bx * 4 + x, v.dims.x - 1),
                                               std::min(by * 4 + y, v.dims.y - 1),
                                               std::min(bz * 4 + z, v.dims.z - 1))));
      },
      2, quiet);
}

}  // namespace

TEST(TvqTransform, DctAndKltBasesAreOrthonormalWithTheMeanFirst) {
  expectOrthonormal(dctBasis(), "DCT");
  expectOrthonormal(kltOf(generateMarschnerLobb(32)), "KLT");
  // A volume whose blocks span only a few directions still gets a full basis.
  expectOrthonormal(kltOf(generateMenger(2)), "KLT of a sparse volume");
}

TEST(TvqTransform, ForwardAndInverseRoundTrip) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-100, 100);
  for (const Basis& b : {dctBasis(), kltOf(generateSheppLogan(32))}) {
    float x[64], c[64], y[64];
    for (float& v : x) v = u(rng);
    b.forward(x, c);
    b.inverse(c, y);
    double mean = 0;
    for (float v : x) mean += v;
    EXPECT_NEAR(c[0] / 8.0, mean / 64.0, 1e-3);  // coefficient 0 is 8 x the mean
    for (int i = 0; i < 64; ++i) EXPECT_NEAR(y[i], x[i], 1e-3);
  }
}

TEST(TvqTransform, KltPutsMoreEnergyInTheLowpassZoneThanTheDct) {
  const Volume v = generateSheppLogan(40);
  const Basis klt = kltOf(v), dct = dctBasis();
  // The KLT's first coefficients capture the variance the DCT spreads out; over all blocks, the
  // part of the AC energy the lowpass zone holds is at least the DCT's.
  double kltLow = 0, kltAll = 0, dctLow = 0, dctAll = 0;
  for (int bz = 0; bz < 10; ++bz)
    for (int by = 0; by < 10; ++by)
      for (int bx = 0; bx < 10; ++bx) {
        float x[64], c[64];
        for (int z = 0, j = 0; z < 4; ++z)
          for (int y = 0; y < 4; ++y)
            for (int xx = 0; xx < 4; ++xx, ++j)
              x[j] = float(v.valueAt(v.index(bx * 4 + xx, by * 4 + y, bz * 4 + z)));
        for (auto [b, low, all] :
             {std::tuple{&klt, &kltLow, &kltAll}, std::tuple{&dct, &dctLow, &dctAll}}) {
          b->forward(x, c);
          for (int k = 1; k < 64; ++k) {
            *all += double(c[k]) * c[k];
            if (b->zone[std::size_t(k)] == 0) *low += double(c[k]) * c[k];
          }
        }
      }
  ASSERT_GT(dctAll, 0);
  std::printf("lowpass share of AC energy: KLT %.3f, DCT %.3f\n", kltLow / kltAll, dctLow / dctAll);
  EXPECT_GE(kltLow / kltAll, dctLow / dctAll - 1e-9);
}

TEST(TvqClassify, ZeroLowpassAndBandpassBlocksTakeTheirClasses) {
  const Basis b = dctBasis();
  float c[64] = {};
  c[0] = 800;  // a constant block
  EXPECT_EQ(classify(b, c, 1e-6, true), kZero);
  c[1] = 20, c[4] = -5;  // (u, v) = (1, 0) and (0, 1): lowpass zone
  EXPECT_EQ(classify(b, c, 1e-6, true), kLp);
  EXPECT_EQ(classify(b, c, 1e-6, false), kHpXyz);  // without classes: one class for all
  c[2] = 7;                                        // u = 2: the x bandpass zone
  EXPECT_EQ(classify(b, c, 1e-6, true), kBpX);
  c[8] = 3;  // v = 2: the y bandpass zone too
  EXPECT_EQ(classify(b, c, 1e-6, true), kBpXyz);
  c[63] = 1;  // (3, 3, 3): the xyz highpass zone
  EXPECT_EQ(classify(b, c, 1e-6, true), kHpXyz);
  // Within the threshold, the small coefficients may be dropped.
  EXPECT_EQ(classify(b, c, 1.0 + 9.0 + 49.0 + 1e-3, true), kLp);
  EXPECT_EQ(classify(b, c, 1e9, true), kZero);
}

TEST(TvqCodec, AnExactlyLowpassVolumeIsCodedLpAndReconstructedWithinTolerance) {
  // Every block a sum of lowpass DCT basis functions: lowpass codebooks alone reconstruct it.
  const Basis b = dctBasis();
  Volume v = Volume::allocate({32, 32, 32}, ScalarType::Float32);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  const int lowpass[] = {1, 4, 16, 5};  // (1,0,0), (0,1,0), (0,0,1), (1,1,0)
  auto data = v.as<float>();
  for (int bz = 0; bz < 8; ++bz)
    for (int by = 0; by < 8; ++by)
      for (int bx = 0; bx < 8; ++bx) {
        // Four kinds of block, so a small lowpass codebook holds them exactly.
        const int kind = (bx + by + bz) % 4;
        float c[64] = {}, x[64];
        c[0] = 8.0f * (10 + kind);
        c[lowpass[kind]] = 4.0f;
        b.inverse(c, x);
        for (int z = 0, j = 0; z < 4; ++z)
          for (int y = 0; y < 4; ++y)
            for (int xx = 0; xx < 4; ++xx, ++j)
              data[v.index(bx * 4 + xx, by * 4 + y, bz * 4 + z)] = x[j];
      }
  v.computeRange();
  Params p = quickTvq();
  p.transform = Transform::Dct, p.dcBits = 16, p.fidelity = 1e-4;
  EncodeStats s;
  const CompressedVolume cv = encodeQuiet(v, p, &s);
  EXPECT_EQ(s.classBlocks[kLp], s.blocks);
  const Volume d = decode(cv.info, cv.view());
  EXPECT_GT(psnr(v, d), 60.0);
}

TEST(TvqCodec, AssociatedCodebookDecodeEqualsDequantizeAndInverseTransform) {
  for (Transform t : {Transform::Klt, Transform::Dct}) {
    const Volume v = generateSheppLogan(30, ScalarType::Int16);
    Params p = quickTvq();
    p.transform = t, p.subvolumeVoxels = 16;
    const CompressedVolume cv = encodeQuiet(v, p);
    const Layout layout(cv.info, cv.view());
    kernels::TvqView view = layout.view();
    // The sums before the view rounds int16 data (a sum a rounding step from .5 may round
    // either way).
    view.decoder.integral = false;
    const double range = v.valueMax - v.valueMin;
    int coded = 0;
    for (int bz = 0; bz < 8; ++bz)
      for (int by = 0; by < 8; ++by)
        for (int bx = 0; bx < 8; ++bx) {
          float c[64], slow[64], fast[64];
          coded += layout.coefficients(bx, by, bz, c);
          layout.basis().inverse(c, slow);
          view.decoder.decode(view.decoder.key(bx, by, bz), fast);
          for (int i = 0; i < 64; ++i) {
            const float clamped = std::clamp(slow[i], float(v.valueMin), float(v.valueMax));
            ASSERT_NEAR(fast[i], clamped, 1e-5 * range)
                << bx << "," << by << "," << bz << " voxel " << i;
          }
        }
    EXPECT_GT(coded, 100);
  }
}

// The host view reads the sections where they lie and makes a sub-volume's associated codebooks
// when a block of it is first decoded: a block holds only its sub-volume's; the range grid and
// decode() make their own and free them; the joined (device) buffer decodes every block alike.
TEST(TvqCodec, TheHostViewMakesASubvolumesCodebooksWhenItsBlocksAreFirstDecoded) {
  const Volume v = generateSheppLogan(40);
  Params p = quickTvq();
  p.subvolumeVoxels = 16;  // 3^3 sub-volumes
  const CompressedVolume cv = encodeQuiet(v, p);
  const Layout layout(cv.info, cv.view());
  EXPECT_EQ(layout.subvolumes(), 27);
  EXPECT_EQ(layout.associatedResidentBytes(), 0u);
  (void)layout.rangeGrid();
  const Volume decoded = layout.decode();
  EXPECT_EQ(layout.associatedResidentBytes(), 0u);

  const kernels::TvqView host = layout.view();
  float block[64];
  host.decoder.decode(host.decoder.key(5, 5, 5), block);  // the middle sub-volume's
  const std::uint64_t one = layout.associatedResidentBytes();
  EXPECT_GT(one, 0u);
  EXPECT_LT(one * 4, layout.associatedBytes());
  host.decoder.decode(host.decoder.key(4, 6, 7), block);  // the same sub-volume
  EXPECT_EQ(layout.associatedResidentBytes(), one);

  const std::vector<std::byte> joined = layout.joinedBytes();
  const kernels::TvqView device = layout.view(joined.data());
  const int blocks = 10;
  for (int bz = 0; bz < blocks; ++bz)
    for (int by = 0; by < blocks; ++by)
      for (int bx = 0; bx < blocks; ++bx) {
        float a[64], b[64];
        host.decoder.decode(host.decoder.key(bx, by, bz), a);
        device.decoder.decode(device.decoder.key(bx, by, bz), b);
        for (int i = 0; i < 64; ++i) {
          const int x = bx * 4 + i % 4, y = by * 4 + i / 4 % 4, z = bz * 4 + i / 16;
          ASSERT_EQ(a[i], b[i]) << bx << "," << by << "," << bz << " voxel " << i;
          ASSERT_EQ(double(a[i]), decoded.valueAt(decoded.index(x, y, z)))
              << x << "," << y << "," << z;
        }
      }
  // Every sub-volume with a coded block (one of only background blocks never needs its books).
  EXPECT_GT(layout.associatedResidentBytes(), one);
  EXPECT_LE(layout.associatedResidentBytes(), layout.associatedBytes());

  // Released (between frames), they are made again by the next decode, which gives the same
  // voxels.
  float before[64], after[64];
  host.decoder.decode(host.decoder.key(5, 5, 5), before);
  layout.releaseAssociated();
  EXPECT_EQ(layout.associatedResidentBytes(), 0u);
  host.decoder.decode(host.decoder.key(5, 5, 5), after);
  EXPECT_EQ(layout.associatedResidentBytes(), one);
  for (int i = 0; i < 64; ++i) ASSERT_EQ(before[i], after[i]) << "voxel " << i;
}

// With a file of tables shared on the host (as the ranks of a job on one host have), two views of
// one file make each sub-volume's codebooks once: the second finds them made and decodes the same
// voxels as a view of its own. Released, the first view attaches again and still finds them.
TEST(TvqCodec, TwoViewsWithASharedTablesFileMakeEachSubvolumesCodebooksOnce) {
  const Volume v = generateSheppLogan(40);
  Params p = quickTvq();
  p.subvolumeVoxels = 16;  // 3^3 sub-volumes
  const CompressedVolume cv = encodeQuiet(v, p);
  const Layout alone(cv.info, cv.view());  // attaches nothing: no shared file yet
  hosttables::create();
  const Layout first(cv.info, cv.view()), second(cv.info, cv.view());
  const kernels::TvqView a = first.view(), b = second.view(), own = alone.view();
  const auto decodeAll = [](const kernels::TvqView& view, std::vector<float>& out) {
    out.resize(10 * 10 * 10 * 64);
    for (int bz = 0, i = 0; bz < 10; ++bz)
      for (int by = 0; by < 10; ++by)
        for (int bx = 0; bx < 10; ++bx, ++i)
          view.decoder.decode(view.decoder.key(bx, by, bz), out.data() + i * 64);
  };
  std::vector<float> fromFirst, fromSecond, fromOwn;
  const auto start = hosttables::counts();
  decodeAll(a, fromFirst);
  const auto afterFirst = hosttables::counts();
  decodeAll(b, fromSecond);
  const auto afterSecond = hosttables::counts();
  decodeAll(own, fromOwn);
  EXPECT_EQ(hosttables::counts().made, afterSecond.made);  // the view of its own shares nothing
  const std::uint64_t made = afterFirst.made - start.made;
  EXPECT_GT(made, 0u);
  EXPECT_LE(made, 27u);
  EXPECT_EQ(afterFirst.found, start.found);
  EXPECT_EQ(afterSecond.made, afterFirst.made);
  EXPECT_EQ(afterSecond.found - afterFirst.found, made);
  EXPECT_EQ(first.associatedResidentBytes(), second.associatedResidentBytes());
  EXPECT_EQ(fromFirst, fromOwn);
  EXPECT_EQ(fromSecond, fromOwn);

  first.releaseAssociated();  // detaches; the second view still holds the slot
  EXPECT_EQ(first.associatedResidentBytes(), 0u);
  decodeAll(a, fromFirst);
  EXPECT_EQ(hosttables::counts().made, afterSecond.made);
  EXPECT_EQ(fromFirst, fromOwn);
  hosttables::leave();
}

TEST(TvqCodec, ProgressiveLevelsImprovePsnrMonotonically) {
  const Volume v = generateSheppLogan(40);
  EncodeStats s;
  const CompressedVolume cv = encodeQuiet(v, quickTvq(), &s);
  const Layout layout(cv.info, cv.view());
  double last = 0;
  for (int l = 0; l < kProgressiveLevels; ++l) {
    const double measured = psnr(v, layout.decode(l));
    EXPECT_DOUBLE_EQ(measured, layout.levelPsnr(l)) << "level " << l;
    EXPECT_DOUBLE_EQ(measured, s.levelPsnr[std::size_t(l)]);
    EXPECT_GT(measured, last) << "level " << l;
    last = measured;
  }
}

TEST(TvqCodec, Float32AndInt16RoundTripWithinTheStoredPsnr) {
  for (ScalarType type : {ScalarType::Float32, ScalarType::Int16, ScalarType::UInt16}) {
    Volume v = generateMarschnerLobb(28, type);
    EncodeStats s;
    const CompressedVolume cv = encodeQuiet(v, quickTvq(), &s);
    EXPECT_EQ(cv.info.type, type);
    const Volume d = decode(cv.info, cv.view());
    EXPECT_EQ(d.type, type);
    EXPECT_DOUBLE_EQ(psnr(v, d), s.levelPsnr[3]) << scalarName(type);
    EXPECT_GT(s.levelPsnr[3], 25.0) << scalarName(type);
    EXPECT_GE(d.valueMin, v.valueMin);
    EXPECT_LE(d.valueMax, v.valueMax);
  }
}

TEST(TvqCodec, EmptySpaceIsUncodedAndCostsAboutABitPerBlock) {
  Volume v = Volume::allocate({64, 64, 64}, ScalarType::UInt8);
  const Volume ball = generateSheppLogan(16);
  for (int z = 0; z < 16; ++z)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x)
        v.as<std::uint8_t>()[v.index(x + 8, y + 8, z + 8)] =
            ball.as<std::uint8_t>()[ball.index(x, y, z)];
  v.computeRange();
  EncodeStats s;
  Params p = quickTvq();
  p.subvolumeVoxels = 64;
  const CompressedVolume cv = encodeQuiet(v, p, &s);
  EXPECT_EQ(s.blocks, 16u * 16 * 16);
  EXPECT_LE(s.coded, 4u * 4 * 4 + 16);  // the ball's blocks (and at most a few more)
  EXPECT_EQ(s.occupancyBytes, 4096u / 8);
  const Volume d = decode(cv.info, cv.view());
  EXPECT_EQ(d.as<std::uint8_t>()[d.index(60, 60, 60)], 0);
}

TEST(TvqCodec, MoreCodeBitsGiveMoreQualityAndTheRateTargetIsMet) {
  const Volume v = generateSheppLogan(48);
  double last = 0;
  for (int bits : {4, 10, 16}) {
    Params p = quickTvq();
    p.codeBits = bits;
    EncodeStats s;
    encodeQuiet(v, p, &s);
    EXPECT_GT(s.levelPsnr[3], last) << bits << " bits";
    last = s.levelPsnr[3];
  }
  // The KLT basis (16 KiB) is half a bit per voxel of this small volume.
  const Volume big = generateSheppLogan(64);
  for (double target : {0.6, 1.0}) {
    Params p = quickTvq();
    p.targetBitsPerVoxel = target;
    EncodeStats s;
    const CompressedVolume cv = encodeQuiet(big, p, &s);
    const double bpv = 8.0 * double(serializeContainer(cv).size()) / double(big.voxelCount());
    std::printf("target %.2f bpv: %.3f bpv (%d code bits), %.2f dB\n", target, bpv, s.codeBits,
                s.levelPsnr[3]);
    // The search counts the sections; the container adds its header and alignment.
    EXPECT_LE(8.0 * double(cv.payloadBytes()) / double(big.voxelCount()), target);
    EXPECT_GT(bpv, target * 0.9);
  }
  Params tiny = quickTvq();
  tiny.targetBitsPerVoxel = 0.001;
  EXPECT_THROW(encodeQuiet(v, tiny), std::invalid_argument);
  // A target above the largest file (13-bit codes everywhere) is refused with that file's size,
  // not met silently by a smaller one.
  Params huge = quickTvq();
  huge.targetBitsPerVoxel = 6;
  try {
    encodeQuiet(big, huge);
    ADD_FAILURE() << "a 6 bits per voxel target was not refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("is above the largest tvq file of this volume"),
              std::string::npos)
        << e.what();
  }
}

// Classification sorts the coded blocks into the ten classes by the zones they need; without it
// every coded block is HPxyz. (The paper's case for classes is perceptual: at equal PSNR, edges
// keep their codevectors. bench/tvq_bench.py measures both at equal rates.)
TEST(TvqCodec, ClassesSortTheBlocksAndWithoutThemEveryCodedBlockIsHpXyz) {
  const Volume v = generateMarschnerLobb(48);  // smooth: many lowpass blocks
  EncodeStats with, without;
  Params p = quickTvq();
  p.codeBits = 14, p.fidelity = 0.02;
  encodeQuiet(v, p, &with);
  p.classified = false;
  encodeQuiet(v, p, &without);
  std::uint64_t withoutOther = 0;
  int classesUsed = 0;
  for (int c = 1; c < kClasses; ++c) {
    if (c != kHpXyz) withoutOther += without.classBlocks[std::size_t(c)];
    classesUsed += with.classBlocks[std::size_t(c)] > 0;
  }
  EXPECT_EQ(withoutOther, 0u);
  EXPECT_EQ(without.classBlocks[kHpXyz] + without.classBlocks[kZero], without.blocks);
  EXPECT_GT(with.classBlocks[kLp], 0u);
  EXPECT_GE(classesUsed, 3);
  std::printf("with classes %.2f dB (%d classes), without %.2f dB\n", with.levelPsnr[3],
              classesUsed, without.levelPsnr[3]);
}

TEST(TvqCodec, RefusesBadParameters) {
  const Volume v = generateSheppLogan(12);
  auto refuses = [&](auto change) {
    Params p = quickTvq();
    change(p);
    EXPECT_THROW(encodeQuiet(v, p), std::invalid_argument);
  };
  refuses([](Params& p) { p.dcBits = 0; });
  refuses([](Params& p) { p.dcBits = 17; });
  refuses([](Params& p) { p.codeBits = 40; });
  refuses([](Params& p) { p.subvolumeVoxels = 6; });
  refuses([](Params& p) { p.subvolumeVoxels = 2048; });
  refuses([](Params& p) { p.fidelity = 1.5; });
  Volume nan = Volume::allocate({8, 8, 8}, ScalarType::Float32);
  nan.as<float>()[3] = std::nanf("");
  EXPECT_THROW(encodeQuiet(nan, quickTvq()), std::invalid_argument);
}

TEST(TvqCorrupt, BadSectionsAreRefusedWithTheirName) {
  const Volume v = generateSheppLogan(20);
  Params p = quickTvq();
  p.subvolumeVoxels = 16;
  const CompressedVolume good = encodeQuiet(v, p);
  ASSERT_NO_THROW(Layout(good.info, good.view()));
  auto refused = [&](const char* what, auto change) {
    CompressedVolume bad = good;
    change(bad);
    try {
      Layout(bad.info, bad.view("bad.vwz"));
      ADD_FAILURE() << what << ": accepted";
    } catch (const FormatError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("bad.vwz"), std::string::npos) << message;
      std::printf("%s: %s\n", what, message.c_str());
    }
  };
  using test::poke;
  using test::section;
  refused("truncated params", [](CompressedVolume& c) { section(c, kParams).resize(40); });
  refused("transform", [](CompressedVolume& c) { poke<std::uint32_t>(section(c, kParams), 0, 7); });
  refused("sub-volume side",
          [](CompressedVolume& c) { poke<std::uint32_t>(section(c, kParams), 4, 0); });
  refused("mean bits",
          [](CompressedVolume& c) { poke<std::uint32_t>(section(c, kParams), 8, 30); });
  refused("mean step", [](CompressedVolume& c) { poke<double>(section(c, kParams), 40, -1.0); });
  refused("sub-volume count",
          [](CompressedVolume& c) { poke<std::uint64_t>(section(c, kParams), 80, 3); });
  refused("basis value", [](CompressedVolume& c) { poke<float>(section(c, kBasis), 100, 1e9f); });
  refused("zone",
          [](CompressedVolume& c) { poke<std::uint8_t>(section(c, kBasis), 64 * 64 * 4 + 5, 9); });
  refused("zone sizes", [](CompressedVolume& c) {
    auto& b = section(c, kBasis);
    const std::uint8_t z = std::uint8_t(b[64 * 64 * 4 + 1]);
    poke<std::uint8_t>(b, 64 * 64 * 4 + 2, std::uint8_t(z == 0 ? 1 : 0));
    poke<std::uint8_t>(b, 64 * 64 * 4 + 1, std::uint8_t(z == 0 ? 1 : 0));
  });
  refused("sub-volume table size", [](CompressedVolume& c) { section(c, kSubvolumes).pop_back(); });
  refused("code bits",
          [](CompressedVolume& c) { poke<std::uint8_t>(section(c, kSubvolumes), 0, 14); });
  refused("coded blocks",
          [](CompressedVolume& c) { poke<std::uint64_t>(section(c, kSubvolumes), 8, 1u << 30); });
  refused("scale", [](CompressedVolume& c) { poke<float>(section(c, kSubvolumes), 16, -1.0f); });
  refused("chapter size",
          [](CompressedVolume& c) { poke<std::uint32_t>(section(c, kSubvolumes), 28, 1u << 20); });
  refused("codebooks size",
          [](CompressedVolume& c) { section(c, kCodebooks).push_back(std::byte{0}); });
  refused("occupancy size", [](CompressedVolume& c) { section(c, kOccupancy).resize(8); });
  refused("occupancy count", [](CompressedVolume& c) {
    auto& o = section(c, kOccupancy);
    o[0] = std::byte(std::uint8_t(o[0]) ^ 1u);
  });
  refused("records size", [](CompressedVolume& c) { section(c, kRecords).pop_back(); });
  // A code past its codebook: record 0 of sub-volume 0 names codevector 2^bits - 1 of a
  // partition whose chapters hold fewer.
  {
    const auto& table = good.sections[2].second;
    ASSERT_EQ(good.sections[2].first, kSubvolumes);
    int partition = -1, bitAt = p.dcBits;
    std::uint32_t sizes[21];
    std::memcpy(sizes, table.data() + 28, sizeof sizes);
    for (int q = 0, first = 0; q < 3; first += chapterCount(q), ++q) {
      const int bits = int(table[std::size_t(q)]);
      std::uint64_t limit = 1;
      for (int c = 0; c < chapterCount(q); ++c) limit += sizes[first + c];
      if (bits > 0 && limit < (1u << bits)) {
        partition = q;
        break;
      }
      bitAt += bits;
    }
    ASSERT_GE(partition, 0) << "every partition's codebook is full: pick another volume";
    const int bits = int(table[std::size_t(partition)]);
    refused("a code past its codebook", [&](CompressedVolume& c) {
      auto& r = section(c, kRecords);
      for (int i = 0; i < bits; ++i)
        r[std::size_t((bitAt + i) / 8)] |= std::byte(std::uint8_t(1u << ((bitAt + i) % 8)));
    });
  }
  refused("missing section", [](CompressedVolume& c) { c.sections.erase(c.sections.begin() + 3); });
}
