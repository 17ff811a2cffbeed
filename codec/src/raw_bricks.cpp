// Raw bricks, the format; section layout in raw_bricks.hpp.
#include <algorithm>
#include <cstring>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec::rawbricks {
namespace {

int shiftFor(int voxels, int minShift, const char* what) {
  for (int s = minShift; s <= 6; ++s)
    if ((1 << s) == voxels) return s;
  throw std::invalid_argument(std::string("raw bricks: ") + what + " must be a power of two from " +
                              std::to_string(1 << minShift) + " to 64 voxels, not " +
                              std::to_string(voxels));
}

class Payload final : public RenderPayload {
 public:
  Payload(const VolumeInfo& info, const SectionSet& sections)
      : type_(info.type), layout_(info, sections) {}
  RangeGrid rangeGrid() const override { return layout_.rangeGrid(); }
  std::span<const std::byte> bytes() const override { return layout_.brickBytes(); }
  AnyView view(const std::byte* base) const override {
    return dispatchScalar(type_,
                          [&](auto t) -> AnyView { return layout_.view<decltype(t)>(base); });
  }

 private:
  ScalarType type_;
  Layout layout_;
};

}  // namespace

CompressedVolume encode(const Volume& volume, const Params& params, Progress& progress) {
  return encode(*memorySource(volume), params, progress);
}

CompressedVolume encode(const VolumeSource& volume, const Params& params, Progress& progress) {
  const int shift = shiftFor(params.brickVoxels, 2, "brick size");
  const int rangeShift = shiftFor(params.rangeCellVoxels, 1, "range cell size");
  const int b = 1 << shift;
  const glm::ivec3 bricks = (volume.dims + b - 1) / b;
  const std::size_t brickCount =
      std::size_t(bricks.x) * std::size_t(bricks.y) * std::size_t(bricks.z);
  const std::size_t edge = std::size_t(b) + 1;  // brick plus its apron
  const std::size_t brickScalars = edge * edge * edge;
  const std::size_t scalar = scalarBytes(volume.type);

  CompressedVolume out;
  out.info = volumeInfo(volume.headerVolume(), kCodecId);

  std::vector<std::byte> paramBytes;
  ByteWriter pw(paramBytes);
  pw.put<std::uint32_t>(std::uint32_t(shift));
  pw.put<std::uint32_t>(std::uint32_t(rangeShift));

  std::vector<std::byte> brickBytes(brickCount * brickScalars * scalar);
  progress.begin("bricking", brickCount);
  // One row of bricks at a time, from its b + 1 slices (the last repeats at the volume's end).
  std::vector<std::byte> window(edge * volume.sliceBytes());
  const std::size_t rowBricks = std::size_t(bricks.x) * std::size_t(bricks.y);
  dispatchScalar(volume.type, [&](auto t) {
    using T = decltype(t);
    const T* src = reinterpret_cast<const T*>(window.data());
    T* dst = reinterpret_cast<T*>(brickBytes.data());
    for (int bz = 0; bz < bricks.z; ++bz) {
      volume.readSlices(bz * b, int(edge), window);
      parallelFor(rowBricks, 0, [&](std::size_t inRow) {
        const int bx = int(inRow % std::size_t(bricks.x));
        const int by = int(inRow / std::size_t(bricks.x));
        T* out = dst + (std::size_t(bz) * rowBricks + inRow) * brickScalars;
        for (int z = 0; z <= b; ++z)
          for (int y = 0; y <= b; ++y) {
            const int vy = std::min(by * b + y, volume.dims.y - 1);
            const T* line = src + (std::size_t(z) * std::size_t(volume.dims.y) + std::size_t(vy)) *
                                      std::size_t(volume.dims.x);
            for (int x = 0; x <= b; ++x) *out++ = line[std::min(bx * b + x, volume.dims.x - 1)];
          }
        progress.advance();
      });
    }
  });
  progress.end();

  // Stored in the volume's own type: the extremes are voxel values, so this is exact.
  const glm::ivec3 cells = (volume.dims + (1 << rangeShift) - 1) >> rangeShift;
  std::vector<std::byte> rangeBytes;
  rangeBytes.reserve(std::size_t(cells.x) * std::size_t(cells.y) * std::size_t(cells.z) * 2 *
                     scalar);
  ByteWriter rw(rangeBytes);
  forEachRangeLayer(volume, 1 << rangeShift,
                    [&](int, std::span<const float> lo, std::span<const float> hi) {
                      dispatchScalar(volume.type, [&](auto t) {
                        using T = decltype(t);
                        for (std::size_t i = 0; i < lo.size(); ++i) {
                          rw.put<T>(T(lo[i]));
                          rw.put<T>(T(hi[i]));
                        }
                      });
                    });

  out.sections.emplace_back(kParams, std::move(paramBytes));
  out.sections.emplace_back(kRanges, std::move(rangeBytes));
  out.sections.emplace_back(kBricks, std::move(brickBytes));
  return out;
}

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  ByteReader p(sections.get(kParams, "params"), sections.source, "raw bricks section 'params'");
  const auto shift = p.get<std::uint32_t>();
  if (shift < 2 || shift > 6) p.fail("brick shift " + std::to_string(shift) + " is not in 2..6");
  brickShift_ = int(shift);
  const auto rangeShift = p.get<std::uint32_t>();
  if (rangeShift < 1 || rangeShift > 6)
    p.fail("range cell shift " + std::to_string(rangeShift) + " is not in 1..6");
  rangeShift_ = int(rangeShift);
  rangeCells_ = (info.dims + (1 << rangeShift_) - 1) >> rangeShift_;
  const std::size_t cellCount =
      std::size_t(rangeCells_.x) * std::size_t(rangeCells_.y) * std::size_t(rangeCells_.z);
  const int b = 1 << brickShift_;
  bricks_ = (info.dims + b - 1) / b;
  const std::size_t brickCount =
      std::size_t(bricks_.x) * std::size_t(bricks_.y) * std::size_t(bricks_.z);
  rangeBytes_ = sections.get(kRanges, "ranges");
  if (rangeBytes_.size() != cellCount * 2 * scalarBytes(info.type))
    throw FormatError(sections.source,
                      "raw bricks section 'ranges': " + std::to_string(rangeBytes_.size()) +
                          " bytes, expected " +
                          std::to_string(cellCount * 2 * scalarBytes(info.type)));
  brickBytes_ = sections.get(kBricks, "bricks");
  const std::size_t expected =
      brickCount * std::size_t((b + 1) * (b + 1) * (b + 1)) * scalarBytes(info.type);
  if (brickBytes_.size() != expected)
    throw FormatError(sections.source,
                      "raw bricks section 'bricks': " + std::to_string(brickBytes_.size()) +
                          " bytes, expected " + std::to_string(expected) + " for " +
                          std::to_string(info.dims.x) + "x" + std::to_string(info.dims.y) + "x" +
                          std::to_string(info.dims.z) + " " + std::string(scalarName(info.type)));
  if (reinterpret_cast<std::uintptr_t>(brickBytes_.data()) % scalarBytes(info.type))
    throw FormatError(sections.source, "raw bricks section 'bricks' is misaligned");
}

RangeGrid Layout::rangeGrid() const {
  RangeGrid grid(1 << rangeShift_, rangeCells_, info_.type);
  ByteReader r(rangeBytes_, "", "ranges");
  dispatchScalar(info_.type, [&](auto t) {
    using T = decltype(t);
    for (std::size_t i = 0; i < grid.cellCount(); ++i) {
      const T lo = r.get<T>();
      grid.set(i, float(lo), float(r.get<T>()));
    }
  });
  return grid;
}

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  const Layout layout(info, sections);
  Volume v = Volume::allocate(info.dims, info.type, info.spacing);
  v.valueMin = info.valueMin;
  v.valueMax = info.valueMax;
  dispatchScalar(info.type, [&](auto t) {
    using T = decltype(t);
    const auto view = layout.view<T>();
    auto dst = v.as<T>();
    parallelFor(std::size_t(info.dims.z), 0, [&](std::size_t z) {
      for (int y = 0; y < info.dims.y; ++y)
        for (int x = 0; x < info.dims.x; ++x)
          dst[v.index(x, y, int(z))] = T(view.voxel(x, y, int(z)));
    });
  });
  return v;
}

std::unique_ptr<RenderPayload> openPayload(const VolumeInfo& info, const SectionSet& sections) {
  return std::make_unique<Payload>(info, sections);
}

DecodedBricks::DecodedBricks(const Volume& volume, const std::string& source) {
  Progress quiet;
  coded_ = encode(volume, Params{}, quiet);
  sections_ = coded_.view(source);
  layout_.emplace(coded_.info, sections_);
}

std::unique_ptr<RenderPayload> DecodedBricks::payload() const {
  return openPayload(coded_.info, sections_);
}

std::uint64_t DecodedBricks::bytesFor(glm::ivec3 dims, ScalarType type) {
  const int b = Params{}.brickVoxels;
  const glm::u64vec3 bricks = (glm::u64vec3(dims) + std::uint64_t(b - 1)) / std::uint64_t(b);
  const auto side = std::uint64_t(b + 1);
  return bricks.x * bricks.y * bricks.z * side * side * side * std::uint64_t(scalarBytes(type));
}

}  // namespace voxwall::codec::rawbricks
