// Every registered codec, through the registry only: what the commands, RenderVolume and the fuzz
// target rely on. A new codec is covered by these tests as soon as it is registered.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <variant>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/kernels/trilinear.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/core/errors.hpp>

using namespace voxwall::codec;

TEST(Registry, NamesAndIdsAreUniqueAndFound) {
  ASSERT_GE(codecs().size(), 3u);
  std::set<std::string_view> names;
  std::set<CodecId> ids;
  for (const Codec* c : codecs()) {
    EXPECT_TRUE(names.insert(c->name()).second) << c->name();
    EXPECT_TRUE(ids.insert(c->id()).second) << c->name();
    EXPECT_EQ(findCodec(c->id()), c);
    EXPECT_EQ(&codecNamed(c->name()), c);
    EXPECT_FALSE(c->summary().empty());
    EXPECT_FALSE(c->samples().empty()) << c->name();
  }
  EXPECT_THROW(codecNamed("nosuchcodec"), std::invalid_argument);
  VolumeInfo info;
  info.codec = CodecId(99);
  EXPECT_THROW(codecOf(info, "x.vwz"), voxwall::FormatError);
}

// The caches of decoded bricks and pages are keyed by a layout's cache id: ids are unique in the
// process whatever the codec (each codec once counted its own from 1, so a vq and a zfp layout
// could share one).
TEST(Registry, EveryOpenedLayoutHasItsOwnCacheId) {
  std::set<std::uint64_t> seen;
  int views = 0;
  for (const Codec* c : codecs())
    for (const CodecSample& sample : c->samples()) {
      const SectionSet sections = sample.volume.view(sample.name);
      std::unique_ptr<RenderPayload> payload;
      try {
        payload = c->open(sample.volume.info, sections);
      } catch (const voxwall::FormatError&) {
        continue;  // a file its codec holds but cannot render (an RGBA svmm volume)
      }
      std::visit(
          [&](const auto& view) {
            if constexpr (requires { view.cacheId; }) {
              ++views;
              EXPECT_TRUE(seen.insert(view.cacheId).second) << sample.name;
            }
          },
          payload->view(nullptr));
    }
  EXPECT_GE(views, 4);  // vq, ksvd, tvq and zfp views carry one
  const std::uint64_t first = mintCacheIds(3);
  EXPECT_GE(mintCacheIds(), first + 3);
}

TEST(Registry, OptionValuesAreParsedAndRefusedWithTheFlagsName) {
  CodecOptionValues v;
  v.set("--n", "12");
  v.set("--x", "0.5");
  v.set("--bad", "12abc");
  EXPECT_EQ(v.integer("--n", 1, 0, 100), 12);
  EXPECT_EQ(v.integer("--missing", 7, 0, 100), 7);
  EXPECT_DOUBLE_EQ(v.number("--x", 0, 0, 1), 0.5);
  EXPECT_EQ(v.text("--missing", "dflt"), "dflt");
  try {
    (void)v.integer("--bad", 1, 0, 100);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--bad must be an integer in 0..100"), std::string::npos);
  }
  EXPECT_THROW((void)v.integer("--n", 1, 0, 10), std::invalid_argument);
  EXPECT_THROW((void)v.number("--x", 0, 1, 2), std::invalid_argument);
}

// The codec's example options on a small volume make a file of that codec, which its own
// decoder, info lines and checks accept.
TEST(Registry, EveryCodecEncodesWithItsExampleOptions) {
  const Volume volume = generateSheppLogan(24);
  for (const Codec* c : codecs()) {
    SCOPED_TRACE(std::string(c->name()));
    CodecOptionValues values;
    const auto opts = c->exampleOptions();
    for (std::size_t i = 0; i < opts.size(); ++i) {
      const bool isFlag = i + 1 == opts.size() || opts[i + 1].starts_with("--");
      values.set(opts[i], isFlag ? "1" : opts[i + 1]);
      if (!isFlag) ++i;
    }
    voxwall::Progress quiet;
    std::string report;
    const CompressedVolume cv = c->encode(volume, values, quiet, report);
    EXPECT_EQ(cv.info.codec, c->id());
    const SectionSet sections = cv.view();
    const Volume d = c->decode(cv.info, sections);
    EXPECT_EQ(d.dims, volume.dims);
    EXPECT_EQ(d.type, volume.type);
    EXPECT_FALSE(c->describe(cv.info, sections).empty());
    EXPECT_NO_THROW(c->verify(cv.info, sections));
  }
}

// Every renderable sample: the payload's view (cached and uncached samples, gradient neighbours)
// equals trilinear interpolation of the codec's own full decode, and the value ranges cover every
// voxel the view interpolates.
TEST(Registry, EveryViewAgreesWithItsCodecsDecoder) {
  for (const Codec* c : codecs())
    for (const CodecSample& s : c->samples()) {
      SCOPED_TRACE(s.name);
      // Through the container, as a file would be read.
      const auto bytes = serializeContainer(s.volume);
      const auto file = ContainerFile::parse(bytes, s.name + ".vwz");
      ASSERT_EQ(&codecOf(file.info(), s.name), c);
      EXPECT_NO_THROW(c->verify(file.info(), file.sections()));
      std::unique_ptr<RenderPayload> payload;
      try {
        payload = c->open(file.info(), file.sections());
      } catch (const voxwall::FormatError& e) {  // a file the codec holds but cannot render
        EXPECT_NE(std::string(e.what()).find("cannot be rendered"), std::string::npos) << e.what();
        continue;
      }
      const Volume d = c->decode(file.info(), file.sections());
      std::vector<float> dense(d.voxelCount());
      dispatchScalar(d.type, [&](auto t) {
        const auto src = d.as<decltype(t)>();
        for (std::size_t i = 0; i < dense.size(); ++i) dense[i] = float(src[i]);
      });
      struct Dense {
        const std::vector<float>* v;
        glm::ivec3 n;
        float voxel(int x, int y, int z) const {
          x = kernels::clampIndex(x, n.x), y = kernels::clampIndex(y, n.y),
          z = kernels::clampIndex(z, n.z);
          return (*v)[(std::size_t(z) * std::size_t(n.y) + std::size_t(y)) * std::size_t(n.x) +
                      std::size_t(x)];
        }
      } reference{&dense, d.dims};
      const RangeGrid ranges = payload->rangeGrid();
      const auto viewOfPayload = payload->view();
      for (int z = 0; z < d.dims.z; ++z)
        for (int y = 0; y < d.dims.y; ++y)
          for (int x = 0; x < d.dims.x; ++x) {
            const int cell = ranges.cellVoxels();
            const std::size_t i = ranges.cellIndex(x / cell, y / cell, z / cell);
            // The voxel the raycaster interpolates: for an integer type, the full decode rounds
            // it to the type, the view does not.
            const float value =
                std::visit([&](const auto& view) { return view.voxel(x, y, z); }, viewOfPayload);
            ASSERT_NEAR(value, reference.voxel(x, y, z), 0.5f + 1e-3f * std::fabs(value));
            ASSERT_LE(ranges.lo(i), value);
            ASSERT_GE(ranges.hi(i), value);
          }
      std::mt19937 rng(5);
      std::uniform_real_distribution<float> ux(-1.5f, float(d.dims.x) + 0.5f),
          uy(-1.5f, float(d.dims.y) + 0.5f), uz(-1.5f, float(d.dims.z) + 0.5f);
      const float tolerance = 1e-3f * float(std::max(1.0, d.valueMax - d.valueMin));
      std::visit(
          [&](const auto& view) {
            typename std::decay_t<decltype(view)>::RayCache cache;
            for (int i = 0; i < 20000; ++i) {
              const float x = ux(rng), y = uy(rng), z = uz(rng);
              const float want =
                  kernels::trilinear(reference, std::clamp(x, 0.0f, float(d.dims.x - 1)),
                                     std::clamp(y, 0.0f, float(d.dims.y - 1)),
                                     std::clamp(z, 0.0f, float(d.dims.z - 1)));
              ASSERT_NEAR(view.sample(x, y, z, cache), want, tolerance)
                  << x << "," << y << "," << z;
              ASSERT_NEAR(view.sampleNear(x, y, z, cache), want, tolerance);
              ASSERT_NEAR(view.sample(x, y, z), want, tolerance);
            }
          },
          payload->view());
    }
}
