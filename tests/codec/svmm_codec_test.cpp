#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/kernels/raw_view.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/core/errors.hpp>

using namespace voxwall;
using namespace voxwall::codec;

namespace {

// Empty space, a noisy slab, smooth ramps and a few constant boxes: every path of the encoder
// (dropped blocks on several levels, kept blocks, padding) is taken.
template <class T>
Volume svmmMixed(glm::ivec3 dims, int lo, int hi, unsigned seed) {
  const ScalarType type = std::is_same_v<T, std::uint8_t>    ? ScalarType::UInt8
                          : std::is_same_v<T, std::uint16_t> ? ScalarType::UInt16
                                                             : ScalarType::Int16;
  Volume v = Volume::allocate(dims, type);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> any(lo, hi);
  auto data = v.as<T>();
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        int value = lo;
        if (z < dims.z / 4)
          value = lo;  // empty
        else if (z < dims.z / 2)
          value = x < dims.x / 2 ? any(rng) : lo + (hi - lo) / 3;  // noise | constant
        else if (z < 3 * dims.z / 4)
          value = lo + (x * 7 + y * 3 + z) % std::max(1, hi - lo + 1);  // ramps
        else
          value = ((x / 8 + y / 8) % 2) ? hi : lo;  // boxes
        data[v.index(x, y, z)] = T(value);
      }
  v.computeRange();
  return v;
}

svmm::Params params(int w, int r, int q = 100, bool stepped = false, bool bc = false) {
  svmm::Params p;
  p.blockWidth = w, p.rootWidth = r, p.quality = q, p.stepped = stepped, p.baseCompression = bc;
  return p;
}

Volume roundTrip(const Volume& v, const svmm::Params& p, svmm::EncodeStats* stats = nullptr) {
  Progress quiet;
  const auto c = svmm::encode(v, p, quiet, stats);
  return svmm::decode(c.info, c.view());
}

void expectEqualVolumes(const Volume& a, const Volume& b, const std::string& what) {
  ASSERT_EQ(a.dims, b.dims) << what;
  ASSERT_EQ(a.type, b.type) << what;
  ASSERT_EQ(a.data.size(), b.data.size()) << what;
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.voxelCount(); ++i) differ += a.valueAt(i) != b.valueAt(i);
  EXPECT_EQ(differ, 0u) << what;
}

// Every voxel through the view's point query equals the full decode.
void expectPointQueriesMatch(const CompressedVolume& c, const Volume& decoded) {
  const svmm::Layout layout(c.info, c.view());
  const auto view = layout.view();
  std::size_t differ = 0;
  for (int z = 0; z < decoded.dims.z; ++z)
    for (int y = 0; y < decoded.dims.y; ++y)
      for (int x = 0; x < decoded.dims.x; ++x)
        differ += double(view.voxel(x, y, z)) != decoded.valueAt(decoded.index(x, y, z));
  EXPECT_EQ(differ, 0u);
}

struct Shape {
  int w, r;
  bool stepped;
};
const Shape kShapes[] = {{2, 4, false}, {4, 8, false}, {8, 8, false},  {4, 64, false},
                         {0, 4, true},  {0, 16, true}, {4, 200, false}};

}  // namespace

TEST(SvmmCodec, QualityMapsToDelta) {
  EXPECT_EQ(svmm::deltaForQuality(100, 1), 0.0);
  EXPECT_EQ(svmm::deltaForQuality(100, 4), 0.0);
  EXPECT_DOUBLE_EQ(svmm::deltaForQuality(0, 1), 1.0);
  EXPECT_DOUBLE_EQ(svmm::deltaForQuality(0, 4), 2.0);
  EXPECT_DOUBLE_EQ(svmm::deltaForQuality(90, 4), 0.2);
  EXPECT_THROW(svmm::deltaForQuality(101, 1), std::invalid_argument);
}

TEST(SvmmCodec, LosslessAtQuality100ForEveryScalarType) {
  const glm::ivec3 dims(37, 29, 23);  // not a multiple of any block or root width
  const Volume volumes[] = {
      svmmMixed<std::uint8_t>(dims, 0, 255, 1), svmmMixed<std::uint16_t>(dims, 0, 4095, 2),
      svmmMixed<std::uint16_t>(dims, 0, 65535, 3), svmmMixed<std::int16_t>(dims, -32768, 32767, 4),
      svmmMixed<std::int16_t>(dims, -1024, 3071, 5)};
  for (const Volume& v : volumes)
    for (const Shape& s : kShapes) {
      const std::string what = std::string(scalarName(v.type)) + " w=" + std::to_string(s.w) +
                               " r=" + std::to_string(s.r) + (s.stepped ? " stepped" : "");
      Progress quiet;
      svmm::EncodeStats stats;
      const auto c = svmm::encode(v, params(s.w, s.r, 100, s.stepped), quiet, &stats);
      const Volume d = svmm::decode(c.info, c.view());
      expectEqualVolumes(v, d, what);
      EXPECT_TRUE(std::isinf(stats.psnr)) << what;
      EXPECT_EQ(stats.levels == 1, s.r >= 37) << what;
      expectPointQueriesMatch(c, d);
    }
}

TEST(SvmmCodec, LosslessRgbaAtQuality100) {
  const svmm::RgbaVolume menger = svmm::generateMengerRgba(3);  // 27^3
  svmm::RgbaVolume noisy;
  noisy.dims = {19, 13, 11};
  std::mt19937 rng(7);
  for (int i = 0; i < 19 * 13 * 11; ++i)
    noisy.rgba.push_back(i % 5 == 0 ? 0u : std::uint32_t(rng()));  // arbitrary alpha too
  for (const svmm::RgbaVolume* v : {&menger, const_cast<const svmm::RgbaVolume*>(&noisy)})
    for (const Shape& s : kShapes) {
      Progress quiet;
      const auto c = svmm::encodeRgba(*v, params(s.w, s.r, 100, s.stepped), quiet);
      const svmm::RgbaVolume d = svmm::decodeRgba(c.info, c.view());
      ASSERT_EQ(d.rgba.size(), v->rgba.size());
      EXPECT_EQ(d.rgba, v->rgba) << "w=" << s.w << " r=" << s.r;
      const svmm::Layout layout(c.info, c.view());
      const auto view = layout.view();
      std::size_t differ = 0, i = 0;
      for (int z = 0; z < v->dims.z; ++z)
        for (int y = 0; y < v->dims.y; ++y)
          for (int x = 0; x < v->dims.x; ++x, ++i) differ += view.fetch(x, y, z) != v->rgba[i];
      EXPECT_EQ(differ, 0u);
    }
}

// Read a slab of base blocks at a time where the view reads them whole, from the leaves
// elsewhere (stepped files, one level): either way the decoded volume's ranges.
TEST(SvmmCodec, RangeGridEqualsTheDecodedVolumes) {
  const Volume v = svmmMixed<std::uint16_t>({45, 38, 30}, 100, 3000, 47);
  for (const Shape& s : kShapes)
    for (int q : {100, 80}) {
      const std::string what = "w=" + std::to_string(s.w) + " r=" + std::to_string(s.r) +
                               (s.stepped ? " stepped" : "") + " q=" + std::to_string(q);
      Progress quiet;
      const auto c = svmm::encode(v, params(s.w, s.r, q, s.stepped), quiet);
      const Volume d = svmm::decode(c.info, c.view());
      const RangeGrid want = computeRangeGrid(d, 4);
      const svmm::Layout layout(c.info, c.view());
      const RangeGrid got = layout.rangeGrid();
      EXPECT_EQ(got.cellVoxels(), 4) << what;
      EXPECT_EQ(got.cells(), want.cells()) << what;
      EXPECT_EQ(got.type(), ScalarType::UInt16) << what;
      EXPECT_TRUE(got == want) << what << (layout.view().baseBlockSide() > 0 ? " (slabs)" : "");
    }
}

TEST(SvmmCodec, ConstantVolumeCollapsesToTheRoot) {
  Volume v = Volume::allocate({70, 50, 33}, ScalarType::UInt16);
  for (auto& x : v.as<std::uint16_t>()) x = 1234;
  v.computeRange();
  svmm::EncodeStats stats;
  const Volume d = roundTrip(v, params(4, 8), &stats);
  ASSERT_GE(stats.levels, 3);
  for (int i = 0; i + 1 < stats.levels; ++i) EXPECT_EQ(stats.blocks[std::size_t(i)], 0u) << i;
  EXPECT_EQ(stats.blocks.back(), 1u);
  expectEqualVolumes(v, d, "constant");
}

TEST(SvmmCodec, OneBrightVoxelKeepsOnePathOfBlocks) {
  for (const Shape& s : kShapes) {
    if (s.r >= 64) continue;
    Volume v = Volume::allocate({45, 40, 35}, ScalarType::UInt8);
    v.as<std::uint8_t>()[v.index(31, 17, 22)] = 200;
    v.computeRange();
    svmm::EncodeStats stats;
    const Volume d = roundTrip(v, params(s.w, s.r, 100, s.stepped), &stats);
    expectEqualVolumes(v, d, "one voxel");
    for (int i = 0; i + 1 < stats.levels; ++i)
      EXPECT_EQ(stats.blocks[std::size_t(i)], 1u) << "level " << i << " w=" << s.w;
  }
}

TEST(SvmmCodec, LossyErrorIsBoundedAndSizeShrinksWithQuality) {
  const Volume v = svmmMixed<std::uint8_t>({48, 40, 36}, 0, 255, 9);
  std::uint64_t lastBytes = ~0ull;
  double lastPsnr = std::numeric_limits<double>::infinity();
  for (int q : {100, 95, 90, 80, 65, 30}) {
    Progress quiet;
    svmm::EncodeStats stats;
    const auto c = svmm::encode(v, params(4, 8, q), quiet, &stats);
    const Volume d = svmm::decode(c.info, c.view());
    double maxErr = 0;
    for (std::size_t i = 0; i < v.voxelCount(); ++i)
      maxErr = std::max(maxErr, std::abs(v.valueAt(i) - d.valueAt(i)));
    const double bound = stats.levels * stats.delta * (v.valueMax - v.valueMin) + 1.0;
    EXPECT_LE(maxErr, bound) << "q=" << q;
    EXPECT_LE(stats.dataBytes, lastBytes) << "q=" << q;
    const double measured = psnr(v, d);
    if (std::isinf(measured)) {
      EXPECT_TRUE(std::isinf(stats.psnr)) << "q=" << q;
    } else {
      EXPECT_NEAR(stats.psnr, measured, 1e-9) << "q=" << q;
    }
    if (q <= 65) {
      EXPECT_FALSE(std::isinf(measured)) << "q=" << q;  // lossy for real
    }
    EXPECT_LE(stats.psnr, lastPsnr + 1e-9) << "q=" << q;
    lastBytes = stats.dataBytes, lastPsnr = stats.psnr;
    expectPointQueriesMatch(c, d);
  }
}

TEST(SvmmCodec, BaseBlockCompressionKeepsOccupancyAndShrinks) {
  const Volume v = svmmMixed<std::uint8_t>({40, 36, 32}, 0, 255, 11);
  Progress quiet;
  for (int w : {2, 4, 8}) {
    svmm::EncodeStats plain, packed;
    const auto a = svmm::encode(v, params(w, 4, 100), quiet, &plain);
    const auto b = svmm::encode(v, params(w, 4, 100, false, true), quiet, &packed);
    EXPECT_LT(packed.dataBytes, plain.dataBytes) << w;
    const Volume d = svmm::decode(b.info, b.view());
    std::size_t occupancyDiffers = 0;
    for (std::size_t i = 0; i < v.voxelCount(); ++i)
      occupancyDiffers += (v.valueAt(i) != 0) != (d.valueAt(i) != 0);
    EXPECT_EQ(occupancyDiffers, 0u) << w;
    expectPointQueriesMatch(b, d);
  }
}

// The encoder reads level 0 a window of slices at a time: windows of one row of blocks give the
// same file as one window of the whole volume, and the PSNR it sums on the way is the decoded
// volume's, for every level count (one level, level 1 as the root, more), block width, base
// compression and scalar type.
TEST(SvmmCodec, WindowsOfOneRowWriteTheSameFileAndItsPsnr) {
  struct Case {
    Volume v;
    svmm::Params p;
    const char* what;
  };
  const auto withWindow = [](svmm::Params p, std::size_t bytes) {
    p.windowBytes = bytes;
    return p;
  };
  std::vector<Case> cases;
  cases.push_back({svmmMixed<std::uint8_t>({37, 30, 29}, 0, 255, 3), params(4, 8, 100), "u8 w4"});
  cases.push_back(
      {svmmMixed<std::uint8_t>({37, 30, 29}, 0, 255, 3), params(4, 8, 70), "u8 w4 q70"});
  cases.push_back(
      {svmmMixed<std::uint8_t>({37, 30, 29}, 0, 255, 3), params(2, 4, 90, true), "u8 stepped q90"});
  cases.push_back({svmmMixed<std::uint8_t>({40, 36, 34}, 0, 255, 5), params(4, 4, 100, false, true),
                   "u8 w4 base compression"});
  cases.push_back(
      {svmmMixed<std::uint16_t>({33, 27, 31}, 0, 4095, 7), params(8, 4, 85), "u16 w8 q85"});
  cases.push_back({svmmMixed<std::int16_t>({30, 31, 26}, -1024, 3071, 9), params(4, 16, 95),
                   "i16 level 1 root"});
  cases.push_back({svmmMixed<std::uint8_t>({12, 9, 7}, 0, 255, 1), params(4, 32), "u8 one level"});
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    Progress quiet;
    svmm::EncodeStats whole, rows;
    const auto a = svmm::encode(c.v, withWindow(c.p, std::size_t(1) << 30), quiet, &whole);
    const auto b = svmm::encode(c.v, withWindow(c.p, 1), quiet, &rows);
    ASSERT_EQ(a.sections.size(), b.sections.size());
    for (std::size_t i = 0; i < a.sections.size(); ++i)
      EXPECT_TRUE(a.sections[i] == b.sections[i]) << "section " << i;
    const double measured = psnr(c.v, svmm::decode(b.info, b.view()));
    if (std::isinf(measured)) {
      EXPECT_TRUE(std::isinf(rows.psnr));
    } else {
      EXPECT_NEAR(rows.psnr, measured, 1e-9 * measured);
    }
  }
  // The cases reach what they name.
  svmm::EncodeStats s;
  Progress quiet;
  svmm::encode(cases[5].v, cases[5].p, quiet, &s);
  EXPECT_EQ(s.levels, 2);
  svmm::encode(cases[6].v, cases[6].p, quiet, &s);
  EXPECT_EQ(s.levels, 1);
}

TEST(SvmmCodec, RefusesFloatAndBadParameters) {
  Progress quiet;
  const Volume f = Volume::allocate({8, 8, 8}, ScalarType::Float32);
  EXPECT_THROW(svmm::encode(f, {}, quiet), std::invalid_argument);
  const Volume u = Volume::allocate({8, 8, 8}, ScalarType::UInt8);
  EXPECT_THROW(svmm::encode(u, params(3, 8), quiet), std::invalid_argument);
  EXPECT_THROW(svmm::encode(u, params(4, 1), quiet), std::invalid_argument);
  EXPECT_THROW(svmm::encode(u, params(4, 8, 101), quiet), std::invalid_argument);
}

namespace {

// Sample positions spread over the volume and a bit outside it (clamped).
std::vector<glm::vec3> positions(glm::ivec3 dims, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ux(-0.5f, float(dims.x) - 0.5f),
      uy(-0.5f, float(dims.y) - 0.5f), uz(-0.5f, float(dims.z) - 0.5f);
  std::vector<glm::vec3> out;
  for (int i = 0; i < n; ++i) out.emplace_back(ux(rng), uy(rng), uz(rng));
  return out;
}

}  // namespace

TEST(SvmmView, TrilinearSamplesEqualTheDecodedVolumes) {
  const Volume v = svmmMixed<std::uint8_t>({41, 35, 30}, 0, 255, 13);
  for (int q : {100, 80}) {
    Progress quiet;
    const auto c = svmm::encode(v, params(4, 8, q), quiet);
    const Volume d = svmm::decode(c.info, c.view());
    const auto raw = rawbricks::encode(d, {}, quiet);
    const rawbricks::Layout rawLayout(raw.info, raw.view());
    const auto rv = rawLayout.view<std::uint8_t>();
    const svmm::Layout layout(c.info, c.view());
    const auto sv = layout.view();
    kernels::SvmmView::RayCache rc;  // one cache across all samples, as along a ray
    std::size_t differ = 0;
    for (const glm::vec3& p : positions(v.dims, 100000, 17)) {
      differ += sv.sample(p.x, p.y, p.z, rc) != rv.sample(p.x, p.y, p.z);
      differ += sv.sampleNear(p.x + 1, p.y, p.z, rc) != rv.sample(p.x + 1, p.y, p.z);
    }
    EXPECT_EQ(differ, 0u) << "q=" << q;
  }
}

TEST(SvmmView, ConstantRegionsHoldOneValue) {
  const Volume v = svmmMixed<std::uint8_t>({64, 48, 40}, 0, 255, 19);
  Progress quiet;
  for (bool nearest : {false, true}) {
    const auto c = svmm::encode(v, params(4, 8, 90), quiet);
    const svmm::Layout layout(c.info, c.view());
    const auto sv = layout.view();
    std::mt19937 rng(23);
    std::size_t regions = 0, wrong = 0, large = 0;
    for (const glm::vec3& p : positions(v.dims, 20000, 29)) {
      kernels::SvmmView::RayCache rc;
      rc.nearest = nearest;
      const float value = sv.sample(p.x, p.y, p.z, rc);
      if (!rc.regionValid) continue;
      ++regions;
      float lo[3], hi[3];
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::max(rc.regionLo[a], -0.5f);
        hi[a] = std::min(rc.regionHi[a], float(v.dims[a]) - 0.5f);
        EXPECT_LE(rc.regionLo[a], p[a] + 1.0f / 32.0f);  // the region keeps a 1/64 margin
        EXPECT_GE(rc.regionHi[a], p[a] - 1.0f / 32.0f);
      }
      large += (hi[0] - lo[0]) >= 3.0f;
      for (int k = 0; k < 8; ++k) {
        std::uniform_real_distribution<float> ux(lo[0], hi[0]), uy(lo[1], hi[1]), uz(lo[2], hi[2]);
        kernels::SvmmView::RayCache fresh;
        fresh.nearest = nearest;
        const float qx = ux(rng), qy = uy(rng), qz = uz(rng);
        wrong += sv.sample(qx, qy, qz, fresh) != value;
        // Gradient neighbours inside the region are answered from it: the same value.
        if (!nearest) wrong += sv.sampleNear(qx, qy, qz, rc) != value;
      }
    }
    EXPECT_GT(regions, 1000u) << nearest;
    EXPECT_GT(large, 100u) << nearest;
    EXPECT_EQ(wrong, 0u) << nearest;
  }
}

TEST(SvmmView, NearestModeReadsTheNearestVoxel) {
  const Volume v = svmmMixed<std::uint8_t>({33, 30, 27}, 0, 255, 31);
  Progress quiet;
  const auto c = svmm::encode(v, params(0, 4, 100, true), quiet);
  const svmm::Layout layout(c.info, c.view());
  const auto sv = layout.view();
  kernels::SvmmView::RayCache rc;
  rc.nearest = true;
  std::size_t differ = 0;
  for (const glm::vec3& p : positions(v.dims, 50000, 37)) {
    const int x = kernels::clampIndex(int(std::lround(p.x)), v.dims.x);
    const int y = kernels::clampIndex(int(std::lround(p.y)), v.dims.y);
    const int z = kernels::clampIndex(int(std::lround(p.z)), v.dims.z);
    const float want = float(v.valueAt(v.index(x, y, z)));
    // lround rounds halves away from zero, the view rounds them up: skip exact halves
    if (std::abs(p.x - std::floor(p.x) - 0.5f) < 1e-4f) continue;
    differ += sv.sample(p.x, p.y, p.z, rc) != want;
  }
  EXPECT_EQ(differ, 0u);
}

TEST(SvmmView, LevelOfDetailReadsBlockAverages) {
  // w = 4: a level-1 voxel is the rounded mean of a 4^3 block of the volume.
  const Volume v = svmmMixed<std::uint8_t>({32, 32, 32}, 0, 255, 41);
  Progress quiet;
  const auto c = svmm::encode(v, params(4, 2), quiet);
  const svmm::Layout layout(c.info, c.view());
  const auto sv = layout.view();
  ASSERT_EQ(sv.lodLevel(4.0f), 1);
  ASSERT_EQ(sv.lodLevel(3.9f), 0);
  std::size_t differ = 0;
  for (int bz = 0; bz < 8; ++bz)
    for (int by = 0; by < 8; ++by)
      for (int bx = 0; bx < 8; ++bx) {
        double sum = 0;
        for (int z = 0; z < 4; ++z)
          for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x)
              sum += v.valueAt(v.index(bx * 4 + x, by * 4 + y, bz * 4 + z));
        const float want = float(std::floor(sum / 64.0 + 0.5));
        kernels::SvmmView::RayCache rc;
        rc.footprint = 4.0f;
        // The level-1 voxel centre in volume index space: (b + 1/2) 4 - 1/2.
        const float got = sv.sample(bx * 4 + 1.5f, by * 4 + 1.5f, bz * 4 + 1.5f, rc);
        differ += got != want;
      }
  EXPECT_EQ(differ, 0u);
}

namespace {

std::vector<std::byte> serialized(const CompressedVolume& c) { return serializeContainer(c); }

// Re-encodes `c` with one params field (at byte offset `at`) replaced and re-serializes it.
CompressedVolume withParamsPatch(CompressedVolume c, std::size_t at, std::uint32_t value) {
  auto& p = c.sections[0].second;
  std::memcpy(p.data() + at, &value, 4);
  return c;
}

void expectSvmmRefused(const CompressedVolume& c, const std::string& needle) {
  const auto bytes = serialized(c);
  try {
    const auto file = ContainerFile::parse(bytes, "bad.vwz");
    (void)svmm::decode(file.info(), file.sections());
    ADD_FAILURE() << "accepted a file with " << needle;
  } catch (const FormatError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bad.vwz"), std::string::npos) << what;
    EXPECT_NE(what.find(needle), std::string::npos) << what;
  }
}

}  // namespace

TEST(SvmmCodec, RefusesCorruptSections) {
  const Volume v = svmmMixed<std::uint8_t>({40, 36, 32}, 0, 255, 43);
  Progress quiet;
  const auto c = svmm::encode(v, params(4, 8, 90), quiet);
  const svmm::Layout ok(c.info, c.view());
  ASSERT_GE(ok.levels(), 3);
  // params: format 0, flags 4, bias 8, quality 12, delta 16, peak 24, r 32, stepped 36,
  // levels 40, root 44..55, then 32 bytes per level: width, shift, blocks, offset, bytes.
  expectSvmmRefused(withParamsPatch(c, 0, 7), "voxel format");
  expectSvmmRefused(withParamsPatch(c, 0, 2), "does not match scalar type");
  expectSvmmRefused(withParamsPatch(c, 4, 2), "flags");
  expectSvmmRefused(withParamsPatch(c, 40, 17), "levels");
  expectSvmmRefused(withParamsPatch(c, 40, 2), "level 1: block width");
  expectSvmmRefused(withParamsPatch(c, 44, 6), "root grid");
  expectSvmmRefused(withParamsPatch(c, 56, 3), "block width");
  expectSvmmRefused(withParamsPatch(c, 56 + 32 + 4, 3), "shift");
  expectSvmmRefused(withParamsPatch(c, 56 + 8, ok.blocks()[0] + 1), "blocks do not fill");
  expectSvmmRefused(withParamsPatch(c, 56 + 16, 3), "outside the section or overlapping");
  {
    auto t = c;
    t.sections[0].second.resize(50);
    expectSvmmRefused(t, "section 'params'");
  }
  {
    auto t = c;
    t.sections.pop_back();
    expectSvmmRefused(t, "missing section");
  }
  {
    // A child offset nibble of the root (level 2's first non-terminal sub-block) changed.
    auto t = c;
    auto& data = t.sections[1].second;
    const auto view = ok.view();
    const std::size_t rootAt =
        std::size_t(view.level[ok.levels() - 1].data -
                    reinterpret_cast<const std::uint8_t*>(ok.dataBytes().data()));
    bool patched = false;
    for (std::size_t i = 0; i < view.level[ok.levels() - 1].blockBytes / 2 && !patched; ++i) {
      std::uint16_t w;
      std::memcpy(&w, data.data() + rootAt + 2 * i, 2);
      if (!(w & kernels::kSvmmTerminal) && (w & 15) == 0) {
        // only patch a voxel whose nibble is zero in a sub-block with a non-zero offset? any
        // change of an offset nibble of a non-terminal sub-block breaks the running count
        w = std::uint16_t(w | 15);
        std::memcpy(data.data() + rootAt + 2 * i, &w, 2);
        patched = true;
      }
    }
    ASSERT_TRUE(patched);
    expectSvmmRefused(t, "sub-block offset");
  }
  {
    // A terminal flag cleared: the level points to more blocks than the next one has.
    auto t = c;
    auto& data = t.sections[1].second;
    const auto view = ok.view();
    const std::size_t at = std::size_t(
        view.level[1].data - reinterpret_cast<const std::uint8_t*>(ok.dataBytes().data()));
    std::size_t flipped = 0;
    for (std::size_t i = 0; i < view.level[1].blockBytes / 2; ++i) {
      std::uint16_t w;
      std::memcpy(&w, data.data() + at + 2 * i, 2);
      if (w & kernels::kSvmmTerminal) {
        w = std::uint16_t(w & ~kernels::kSvmmTerminal);
        std::memcpy(data.data() + at + 2 * i, &w, 2);
        ++flipped;
      }
    }
    ASSERT_GT(flipped, 0u);
    expectSvmmRefused(t, "level 1");
  }
}

TEST(SvmmView, BlockPoolShapeAndPlacement) {
  // Section 3.3: U = V a power of two near the cube root, every block at its own place.
  for (std::uint64_t n : {1ull, 2ull, 7ull, 8ull, 9ull, 63ull, 64ull, 65ull, 1000ull, 4097ull}) {
    const auto s = kernels::svmmPoolShape(n);
    const std::uint64_t U = 1ull << s.uLog2, V = 1ull << s.vLog2;
    EXPECT_EQ(U, V);
    EXPECT_LE(U * U * U, n);
    EXPECT_GT(2 * U * 2 * U * 2 * U, n);
    EXPECT_GE(U * V * s.w, n);
    EXPECT_LT(U * V * (s.w - 1), n);
    std::vector<char> seen(std::size_t(U * V * s.w), 0);
    for (std::uint64_t b = 0; b < n; ++b) {
      std::uint64_t u, v, w;
      kernels::svmmPoolBlock(b, s.uLog2, s.vLog2, u, v, w);
      ASSERT_LT(u, U);
      ASSERT_LT(v, V);
      ASSERT_LT(w, s.w);
      EXPECT_EQ(seen[std::size_t((w * V + v) * U + u)]++, 0) << n << " " << b;
    }
  }
}

TEST(SvmmView, PooledLevelsReadTheSameVoxels) {
  // The CUDA backend's layout, on the host: every poolable level read from its pool image.
  for (bool bc : {false, true}) {
    const Volume v = svmmMixed<std::uint16_t>({45, 37, 29}, 0, 4095, 53);
    Progress quiet;
    const auto c = svmm::encode(v, params(0, 4, 90, true, bc), quiet);
    const svmm::Layout layout(c.info, c.view());
    auto pooled = layout.view();
    std::vector<std::vector<std::uint8_t>> pools(std::size_t(layout.levels()));
    int used = 0;
    for (int L = 0; L < layout.levels(); ++L) {
      if (!layout.poolable(L)) continue;
      pools[std::size_t(L)] = layout.poolBytes(L);
      const auto shape = layout.poolShape(L);
      pooled.level[L].pool = pools[std::size_t(L)].data();
      pooled.level[L].poolULog2 = shape.uLog2, pooled.level[L].poolVLog2 = shape.vLog2;
      ++used;
    }
    EXPECT_EQ(used, layout.levels() - 1 - (bc ? 1 : 0));
    const auto linear = layout.view();
    std::size_t differ = 0;
    for (int z = 0; z < v.dims.z; ++z)
      for (int y = 0; y < v.dims.y; ++y)
        for (int x = 0; x < v.dims.x; ++x) differ += pooled.fetch(x, y, z) != linear.fetch(x, y, z);
    EXPECT_EQ(differ, 0u);
    kernels::SvmmView::RayCache a, b;
    for (const glm::vec3& p : positions(v.dims, 20000, 59))
      differ += pooled.sample(p.x, p.y, p.z, a) != linear.sample(p.x, p.y, p.z, b);
    EXPECT_EQ(differ, 0u);
  }
}
