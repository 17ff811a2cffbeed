// libFuzzer target for the wall protocol as the sink reads it: the input is a byte stream cut
// into messages by MessageReader; every message goes through its payload decoder, and tiles are
// decoded as the sink would (JPEG, raw, deflate). Anything but FormatError is a bug. Fuzzing
// builds skip the wire checksums (FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION), so mutated
// messages reach the decoders.
#include <cstdint>
#include <voxwall/core/errors.hpp>
#include <voxwall/net/wire.hpp>

using namespace voxwall;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  net::MessageReader reader("fuzz");
  // The first byte says where to cut the rest in two, so partial headers and payloads are
  // exercised; it is not part of the stream (the seeds start with it).
  if (size == 0) return 0;
  const std::span all(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  const std::size_t cut = data[0] % (all.size() + 1);
  try {
    for (const auto piece : {all.first(cut), all.subspan(cut)}) {
      reader.feed(piece);
      while (auto m = reader.next()) {
        switch (m->type) {
          case net::MessageType::Hello:
            net::decodeHello(m->payload, "fuzz");
            break;
          case net::MessageType::Welcome:
            net::decodeWelcome(m->payload, "fuzz");
            break;
          case net::MessageType::Tile: {
            const auto t = net::decodeTileMessage(m->payload, "fuzz");
            if (t.rect.area() <= 256 * 256)
              net::decodeTile(t.bytes, t.codec, t.rect.width, t.rect.height, "fuzz");
            break;
          }
          case net::MessageType::FrameEnd:
            net::decodeFrameEnd(m->payload, "fuzz");
            break;
          case net::MessageType::Control:
            net::decodeControl(m->payload, "fuzz");
            break;
          case net::MessageType::Bye:
            net::decodeBye(m->payload, "fuzz");
            break;
          case net::MessageType::FrameNote:
            net::describe(m->frame, net::decodeFrameNote(m->payload, "fuzz"));
            break;
          case net::MessageType::Playback:
            net::decodePlayback(m->payload, "fuzz");
            break;
          case net::MessageType::KeepAlive:
            break;
        }
      }
    }
  } catch (const FormatError&) {
  }
  return 0;
}
