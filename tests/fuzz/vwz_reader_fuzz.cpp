// libFuzzer target: arbitrary bytes as a .vwz file, through the container reader and, when that
// accepts them, the codec's section parser, decoder and range grid.
#include <cstddef>
#include <cstdint>
#include <span>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/errors.hpp>
#include <voxwall/codec/raw_codec.hpp>
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
  } catch (const voxwall::FormatError&) {
  }
  return 0;
}
