// CachedBrickView with decoders of other brick sizes and value types than vq's: every sample,
// cached or not, equals trilinear interpolation of the voxels the decoder produces; and the view
// contract (kernels/view_concept.hpp) accepts every view and refuses what breaks it.
#include <gtest/gtest.h>

#include <random>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/kernels/raw_view.hpp>
#include <voxwall/codec/kernels/svmm_view.hpp>
#include <voxwall/codec/kernels/view_concept.hpp>
#include <voxwall/codec/kernels/vq_view.hpp>

using namespace voxwall::codec;
using namespace voxwall::codec::kernels;

namespace {

// A volume given by a formula, "stored" as bricks of Side^3 voxels: the key is the brick's index
// and decoding evaluates the formula. Counts decodes so the cache can be observed.
template <int Side, class V>
struct FormulaDecoder {
  static constexpr int kBrickSide = Side;
  using Value = V;
  int bricksX = 0, bricksY = 0;
  float offset = 0;
  int* decodes = nullptr;
  static float value(int x, int y, int z) {
    return float((x * 7 + y * 13 + z * 29) % 97) + 0.25f * float((x ^ y ^ z) & 3);
  }
  std::uint64_t key(int bx, int by, int bz) const {
    return (std::uint64_t(bz) * std::uint64_t(bricksY) + std::uint64_t(by)) *
               std::uint64_t(bricksX) +
           std::uint64_t(bx);
  }
  void decode(std::uint64_t key, Value* out) const {
    if (decodes) ++*decodes;
    const int n = Side;
    const int bx = int(key % std::uint64_t(bricksX)),
              by = int(key / std::uint64_t(bricksX)) % bricksY,
              bz = int(key / (std::uint64_t(bricksX) * std::uint64_t(bricksY)));
    for (int z = 0; z < n; ++z)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
          out[x + n * (y + n * z)] = Value(value(bx * n + x, by * n + y, bz * n + z));
  }
  float scalar(Value v) const { return float(v) + offset; }
};

template <int Side, class V>
CachedBrickView<FormulaDecoder<Side, V>> makeView(glm::ivec3 dims, std::uint64_t id, int* decodes) {
  CachedBrickView<FormulaDecoder<Side, V>> v;
  v.setDims(dims.x, dims.y, dims.z);
  v.decoder.bricksX = v.bricksX, v.decoder.bricksY = v.bricksY;
  v.decoder.offset = -3.0f;
  v.decoder.decodes = decodes;
  v.cacheId = id;
  return v;
}

template <int Side, class V>
void expectTrilinearEverywhere(glm::ivec3 dims, std::uint64_t id) {
  const auto view = makeView<Side, V>(dims, id, nullptr);
  struct Reference {
    glm::ivec3 n;
    float voxel(int x, int y, int z) const {
      x = clampIndex(x, n.x), y = clampIndex(y, n.y), z = clampIndex(z, n.z);
      return float(V(FormulaDecoder<Side, V>::value(x, y, z))) - 3.0f;
    }
  } ref{dims};
  std::mt19937 rng{unsigned(id)};
  std::uniform_real_distribution<float> u(-2.0f, float(std::max({dims.x, dims.y, dims.z})) + 1.0f);
  typename decltype(view)::RayCache cache;
  for (int i = 0; i < 50000; ++i) {
    const float x = u(rng), y = u(rng), z = u(rng);
    const float want =
        trilinear(ref, std::clamp(x, 0.0f, float(dims.x - 1)),
                  std::clamp(y, 0.0f, float(dims.y - 1)), std::clamp(z, 0.0f, float(dims.z - 1)));
    ASSERT_FLOAT_EQ(view.sample(x, y, z, cache), want) << x << "," << y << "," << z;
    ASSERT_FLOAT_EQ(
        view.sampleNear(x + 0.5f, y, z, cache),
        trilinear(ref, std::clamp(x + 0.5f, 0.0f, float(dims.x - 1)),
                  std::clamp(y, 0.0f, float(dims.y - 1)), std::clamp(z, 0.0f, float(dims.z - 1))));
    ASSERT_FLOAT_EQ(view.sample(x, y, z), want);
  }
  // The value ranges are those of their cell dilated by one voxel, exactly: what
  // computeRangeGrid takes from the decoded volume. So too when each task's slices hold only one
  // brick's rows of cells in y (the slab bound below one row's bytes): the tasks' y chunks meet
  // without a gap or a missed neighbour, as do their segments in z (about four tasks a core).
  const RangeGrid g = brickRangeGrid(view, ScalarType::Float32);
  const RangeGrid chunked = brickRangeGrid(view, ScalarType::Float32, 1);
  // Cells of 4 voxels, or of 2 in bricks of 2.
  EXPECT_EQ(g.cellVoxels(), Side == 2 ? 2 : 4);
  Volume dense = Volume::allocate(dims, ScalarType::Float32);
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) dense.as<float>()[dense.index(x, y, z)] = ref.voxel(x, y, z);
  const RangeGrid want = computeRangeGrid(dense, g.cellVoxels());
  ASSERT_EQ(g.cells(), want.cells());
  EXPECT_TRUE(g == want);
  EXPECT_TRUE(chunked == want);
  // The full decode holds every voxel.
  const Volume d = decodeBricks(view, ScalarType::Float32, {1, 1, 1});
  ASSERT_EQ(d.dims, dims);
  EXPECT_EQ(d.as<float>()[d.index(dims.x - 1, 0, dims.z - 1)],
            ref.voxel(dims.x - 1, 0, dims.z - 1));
}

}  // namespace

TEST(CachedBrickView, SamplesEqualTrilinearForEveryBrickSizeAndValueType) {
  expectTrilinearEverywhere<2, std::uint8_t>({9, 6, 5}, 101);
  expectTrilinearEverywhere<4, std::uint16_t>({13, 9, 17}, 102);
  expectTrilinearEverywhere<8, float>({21, 16, 11}, 103);
  expectTrilinearEverywhere<16, float>({33, 18, 20}, 104);
  // Sides that are not powers of two (ksvd's 6^3 blocks).
  expectTrilinearEverywhere<6, float>({25, 13, 19}, 105);
  expectTrilinearEverywhere<3, std::uint16_t>({10, 7, 8}, 106);
}

TEST(CachedBrickView, ABrickIsDecodedOnceWhileItStaysCached) {
  int decodes = 0;
  const auto view = makeView<8, float>({16, 16, 16}, 201, &decodes);
  decltype(view)::RayCache cache;
  for (int i = 0; i < 100; ++i) (void)view.sample(2.5f + 0.01f * float(i), 3.5f, 4.5f, cache);
  EXPECT_EQ(decodes, 1);
  // Another ray on the same thread finds the brick in the host cache.
  decltype(view)::RayCache other;
  (void)view.sample(5.5f, 5.5f, 5.5f, other);
  EXPECT_EQ(decodes, 1);
  // A cell across the corner of eight bricks decodes each of them once.
  (void)view.sample(7.5f, 7.5f, 7.5f, other);
  EXPECT_EQ(decodes, 8);
  // A different volume (cacheId) never reads this one's bricks.
  const auto second = makeView<8, float>({16, 16, 16}, 202, &decodes);
  decltype(second)::RayCache c2;
  (void)second.sample(2.5f, 3.5f, 4.5f, c2);
  EXPECT_EQ(decodes, 9);
}

// The contract is checked at compile time; these pin what it accepts and refuses.
struct NoNeighbour {  // lacks sampleNear
  struct RayCache {};
  int dimX = 0, dimY = 0, dimZ = 0;
  float sample(float, float, float, RayCache&) const { return 0; }
  float sample(float, float, float) const { return 0; }
  float voxel(int, int, int) const { return 0; }
};
struct TraversalWithoutRegion {  // declares kTraversal but its cache lacks the region fields
  static constexpr bool kTraversal = true;
  struct RayCache {
    float footprint = 0;
    bool nearest = false;
  };
  int dimX = 0, dimY = 0, dimZ = 0;
  float sample(float, float, float, RayCache&) const { return 0; }
  float sampleNear(float, float, float, RayCache&) const { return 0; }
  float sample(float, float, float) const { return 0; }
  float voxel(int, int, int) const { return 0; }
};
static_assert(VolumeView<RawView<std::uint8_t>> && VolumeView<RawView<float>>);
static_assert(VolumeView<VqView> && !TraversalView<VqView>);
static_assert(VolumeView<SvmmView> && TraversalView<SvmmView>);
static_assert(VolumeView<CachedBrickView<FormulaDecoder<8, float>>>);
static_assert(!VolumeView<NoNeighbour>);
static_assert(VolumeView<TraversalWithoutRegion> && !TraversalView<TraversalWithoutRegion>);
static_assert(!BrickDecoder<int>);
static_assert(BrickView<VqView> && !BrickView<RawView<float>> && !BrickView<SvmmView>);
