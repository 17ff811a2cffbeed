// libFuzzer target: arbitrary bytes as a .vwz file, through the container reader and, when that
// accepts them, the registered codec's checks (section parser, decoder, range grid: Codec::verify)
// and, for a renderable file, samples through its view; a series' steps each.
#include <cstddef>
#include <cstdint>
#include <span>
#include <variant>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/render_payload.hpp>
#include <voxwall/core/errors.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace voxwall::codec;
  try {
    const auto bytes = std::as_bytes(std::span(data, size));
    const auto file = ContainerFile::parse(bytes, "fuzz.vwz");
    const Codec& codec = codecOf(file.info(), "fuzz.vwz");
    // Every step of a series (at most four of them: the bytes are few) is a volume to verify.
    for (int k = 1; k < file.stepCount() && k < 4; ++k)
      codec.verify(file.stepInfo(k), file.stepSections(k));
    codec.verify(file.stepInfo(0), file.sections());
    // The view on a validated file: corners, and samples along a diagonal through a cache.
    const auto payload = codec.open(file.stepInfo(0), file.sections());
    (void)payload->rangeGrid();
    const auto d = file.info().dims;
    std::visit(
        [&](const auto& view) {
          typename std::decay_t<decltype(view)>::RayCache cache;
          volatile float sink = 0;
          for (int i = 0; i <= 16; ++i) {
            const float t = float(i) / 16.0f;
            sink = sink + view.sample(t * float(d.x), t * float(d.y), t * float(d.z), cache) +
                   view.sampleNear(t * float(d.x) + 1, t * float(d.y), t * float(d.z), cache) +
                   view.voxel(d.x - i, i, d.z / 2);
          }
        },
        payload->view());
  } catch (const voxwall::FormatError&) {
  }
  return 0;
}
