#include <algorithm>
#include <bit>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <numbers>
#include <stdexcept>
#include <vector>
#include <voxwall/core/parallel.hpp>
#include <voxwall/node/renderer.hpp>

namespace voxwall::node {

FramePlan planFrame(const RenderVolume& volume, const Camera& camera, int screenWidth,
                    int screenHeight, const TransferFunction& tf, const RenderSettings& settings,
                    const FramePlan* reuse) {
  if (screenWidth <= 0 || screenHeight <= 0)
    throw std::invalid_argument("screen size must be positive");
  if (!(settings.stepVoxels > 0)) throw std::invalid_argument("ray step must be positive");
  const auto& info = volume.info();
  FramePlan plan;
  auto& r = plan.ray;
  const glm::dvec3 forward = glm::normalize(camera.center - camera.eye);
  glm::dvec3 right = glm::cross(forward, camera.up);
  if (glm::length(right) < 1e-12)
    throw std::invalid_argument("camera up vector is parallel to the view");
  right = glm::normalize(right);
  const glm::dvec3 up = glm::cross(right, forward);
  const double tanY = std::tan(camera.fovYDeg * std::numbers::pi / 360.0);
  const double tanX = tanY * double(screenWidth) / double(screenHeight);
  // The camera lives in patient space (LPS axes, origin at the volume's centre); the rays are
  // cast in the grid's own axes. The direction matrix is orthonormal (a rotation, perhaps with a
  // mirror), so its transpose takes patient vectors to grid vectors; the screen's right and up
  // are mapped as they are, not recomputed, so a mirrored grid renders unmirrored.
  const glm::dmat3 toGrid = glm::transpose(info.orientation.direction);
  r.eyeWorld = glm::vec3(toGrid * camera.eye);
  r.forward = glm::vec3(toGrid * forward);
  r.right = glm::vec3(toGrid * (right * tanX));
  r.up = glm::vec3(toGrid * (up * tanY));
  r.screen = {screenWidth, screenHeight};
  r.invSpacing = glm::vec3(1.0 / info.spacing);
  r.centerIndex = glm::vec3((glm::dvec3(info.dims) - 1.0) * 0.5);
  r.boxMax = glm::vec3(glm::dvec3(info.dims) - 0.5);
  const double minSpacing = std::min({info.spacing.x, info.spacing.y, info.spacing.z});
  r.stepWorld = float(settings.stepVoxels * minSpacing);
  r.earlyTermination = float(settings.earlyTerminationOpacity);
  r.shading = settings.shading;
  r.cellGradients = settings.cellGradients;
  r.nearest = settings.nearest;
  // A pixel spans 2 tan(fovY / 2) / height radians; in voxels of the largest spacing (the
  // fewest voxels, so a level is never coarser than the footprint on any axis).
  const double maxSpacing = std::max({info.spacing.x, info.spacing.y, info.spacing.z});
  r.lodAngle =
      settings.levelOfDetail ? float(2.0 * tanY / double(screenHeight) / maxSpacing) : 0.0f;

  plan.lodUnderPressure = settings.lodUnderPressure;
  if (settings.latticeStride < 0 || settings.latticeStride > kMaxLatticeStride ||
      (settings.latticeStride & (settings.latticeStride - 1)) != 0)
    throw std::invalid_argument("ray lattice stride must be 0 (auto) or a power of two up to " +
                                std::to_string(kMaxLatticeStride));
  if (settings.refineAboveLevels < 0)
    throw std::invalid_argument("the lattice's refinement threshold must not be negative");
  plan.latticeStride = settings.latticeStride > 0 ? settings.latticeStride
                                                  : autoLatticeStride(info, camera, screenHeight);
  plan.refineAboveLevels = settings.refineAboveLevels;

  if (reuse) {
    plan.lut = reuse->lut;
    plan.emptyCells = reuse->emptyCells;  // shared: the grids are never written once made
    plan.fineEmptyBits = reuse->fineEmptyBits;
    plan.emptyFraction = reuse->emptyFraction;
    plan.fineEmptyFraction = reuse->fineEmptyFraction;
    plan.skip = reuse->skip;
    return plan;
  }
  plan.lut = tf.bake(tf.domainMin(), tf.domainMax(), settings.stepVoxels, settings.lutEntries,
                     settings.preIntegrate);

  const auto& ranges = volume.ranges();
  int shift = 0;
  while ((1 << shift) < ranges.cellVoxels()) ++shift;
  const glm::ivec3 cells = ranges.cells();
  if (settings.emptySpaceSkipping && (1 << shift) == ranges.cellVoxels() &&
      ranges.cellCount() > 0) {
    int factorShift = 0;
    while ((1 << factorShift) < settings.coarseCellFactor) ++factorShift;
    if ((1 << factorShift) != settings.coarseCellFactor)
      throw std::invalid_argument("coarse skip cell factor must be a power of two");
    // Fine cells straight from the codec's ranges, a bit each.
    const std::size_t fineCount = ranges.cellCount();
    auto fineBits = std::make_shared<std::vector<std::uint32_t>>((fineCount + 31) / 32, 0u);
    auto& bits = *fineBits;
    // Chunk by chunk on every core (the ranges are packed: each task inflates its own chunk); a
    // chunk is whole 32-bit words of bits, so no two tasks write one word.
    static_assert(codec::RangeGrid::kChunkCells % 32 == 0);
    // uint8 ranges take 256 x 256 values: where cells outnumber them, whether each pair is empty
    // is asked once, and a cell reads its pair's answer (the query per cell, about 50 ns, was 7% of
    // a one-small-frame job on a 119 Mvox uint8 MRI, and most of a plan made anew when the transfer
    // function changes).
    std::vector<std::uint8_t> emptyPair;
    if (ranges.type() == codec::ScalarType::UInt8 && fineCount > 256 * 256) {
      emptyPair.resize(256 * 256);
      parallelFor(256, 0, [&](std::size_t lo) {
        for (std::size_t hi = 0; hi < 256; ++hi)
          emptyPair[lo * 256 + hi] = plan.lut.maxOpacity(float(lo), float(hi)) <= 0.0f;
      });
    }
    ranges.forEachParallel(0, [&](std::size_t c, float lo, float hi) {
      const bool empty = emptyPair.empty()
                             ? plan.lut.maxOpacity(lo, hi) <= 0.0f
                             : emptyPair[std::size_t(lo) * 256 + std::size_t(hi)] != 0;
      if (empty) bits[c >> 5] |= 1u << (c & 31);
    });
    std::size_t fineEmpty = 0;
    for (const std::uint32_t word : bits) fineEmpty += std::size_t(std::popcount(word));
    auto isFineEmpty = [&](std::size_t c) { return (bits[c >> 5] >> (c & 31)) & 1u; };
    // A coarse cell is empty when all its fine cells are.
    const glm::ivec3 coarse = (cells + (1 << factorShift) - 1) >> factorShift;
    const std::size_t coarseCount =
        std::size_t(coarse.x) * std::size_t(coarse.y) * std::size_t(coarse.z);
    auto emptyCells = std::make_shared<std::vector<std::uint8_t>>(coarseCount, 1);
    auto& coarseEmpty = *emptyCells;
    for (int z = 0; z < cells.z; ++z)
      for (int y = 0; y < cells.y; ++y)
        for (int x = 0; x < cells.x; ++x) {
          const std::size_t fine =
              (std::size_t(z) * std::size_t(cells.y) + std::size_t(y)) * std::size_t(cells.x) +
              std::size_t(x);
          const std::size_t c = (std::size_t(z >> factorShift) * std::size_t(coarse.y) +
                                 std::size_t(y >> factorShift)) *
                                    std::size_t(coarse.x) +
                                std::size_t(x >> factorShift);
          coarseEmpty[c] &= std::uint8_t(isFineEmpty(fine));
        }
    std::size_t empty = 0;
    for (auto e : coarseEmpty) empty += e;
    plan.emptyFraction = double(empty) / double(coarseCount);
    plan.fineEmptyFraction = double(fineEmpty) / double(fineCount);
    plan.skip.empty = coarseEmpty.data();
    plan.skip.cellsX = coarse.x;
    plan.skip.cellsY = coarse.y;
    plan.skip.cellsZ = coarse.z;
    plan.skip.cellShift = shift + factorShift;
    plan.skip.fineEmpty = bits.data();
    plan.skip.fineX = cells.x;
    plan.skip.fineY = cells.y;
    plan.skip.fineZ = cells.z;
    plan.skip.fineShift = shift;
    plan.emptyCells = std::move(emptyCells);
    plan.fineEmptyBits = std::move(fineBits);
  }
  return plan;
}

}  // namespace voxwall::node
