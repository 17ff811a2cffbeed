// libFuzzer target: arbitrary bytes as a .vwz file, through the container reader and, when that
// accepts them, the codec's section parser, decoder and range grid.
#include <cstddef>
#include <cstdint>
#include <span>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/errors.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/vq_codec.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace voxwall::codec;
  try {
    const auto bytes = std::as_bytes(std::span(data, size));
    const auto file = ContainerFile::parse(bytes, "fuzz.vwz");
    if (file.info().codec == CodecId::Raw) {
      const raw::Layout layout(file.info(), file.sections());
      (void)layout.rangeGrid();
      (void)raw::decode(file.info(), file.sections());
    }
    if (file.info().codec == CodecId::Vq) {
      const vq::Layout layout(file.info(), file.sections());
      (void)layout.rangeGrid();
      (void)vq::decode(file.info(), file.sections());
    }
    if (file.info().codec == CodecId::Svmm) {
      const svmm::Layout layout(file.info(), file.sections());
      (void)layout.rangeGrid();
      if (layout.format() == kernels::kSvmmRgba32)
        (void)svmm::decodeRgba(file.info(), file.sections());
      else
        (void)svmm::decode(file.info(), file.sections());
      // The view on a validated file: corners, and samples along a diagonal through a cache.
      const auto view = layout.view();
      const auto d = file.info().dims;
      kernels::SvmmView::RayCache cache;
      volatile float sink = 0;
      for (int i = 0; i <= 16; ++i) {
        const float t = float(i) / 16.0f;
        sink = sink + view.sample(t * float(d.x), t * float(d.y), t * float(d.z), cache) +
               view.sampleNear(t * float(d.x) + 1, t * float(d.y), t * float(d.z), cache) +
               view.voxel(d.x - i, i, d.z / 2);
      }
    }
  } catch (const voxwall::FormatError&) {
  }
  return 0;
}
