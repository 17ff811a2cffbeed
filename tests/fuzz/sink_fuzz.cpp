// libFuzzer target for the sink's session logic and frame assembly, without sockets: the input
// (after a first byte that picks the wall and limits) is a byte stream of wire messages from a
// sequence of peers. Each message goes through the same steps as on a socket: header check,
// the payload limit before Hello, payload check, SinkCore::handle (handshake, token, jobs,
// tiles into the FrameAssembler), and every presented frame decoded as the file writer would. A
// peer that breaks the protocol is dropped and the next bytes come from a new peer. Anything but a
// clean return is a bug; so is an open frame holding more than the memory limit.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <voxwall/core/errors.hpp>
#include <voxwall/walls/frame_pixels.hpp>
#include <voxwall/walls/sink_core.hpp>

using namespace voxwall;

namespace {

struct FuzzPeer final : net::Peer {
  FuzzPeer() : net::Peer("fuzz peer") {}
  void send(std::vector<std::byte> bytes) override { sent += bytes.size(); }
  void hangUp() override { hungUp = true; }
  std::size_t sent = 0;
  bool hungUp = false;
};

const walls::Wall& wallFor(std::uint8_t pick) {
  static const walls::Wall small = walls::parseWall(
      R"({"wall": "w", "display": {"width": 40, "height": 30}, "bezel_px": {"x": 4, "y": 2},
          "grid": {"columns": 2, "rows": 2}})",
      "fuzz");
  static const walls::Wall one = walls::singleDisplayWall(64, 48);
  return pick & 1 ? one : small;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  walls::SinkSettings settings;
  settings.wall = wallFor(data[0]);
  settings.token = data[0] & 2 ? "token" : "";
  settings.pendingFrames = 1 + (data[0] >> 2) % 4;
  settings.frameWindow = data[0] & 0x40 ? 8 : walls::kDefaultFrameWindow;
  settings.pendingBytes = data[0] & 0x80 ? 64 * 1024 : 0;
  int presented = 0;
  walls::SinkCore core(settings, {}, [&](std::uint64_t, walls::AssembledFrame&& f) {
    // A presented frame's segments lie on the screen; decoding them (as the file writer and the
    // overview do) gives a whole screen or a FormatError (a corrupt body behind a good header).
    for (const auto& s : f.segments)
      if (!s.screen.fitsIn(settings.wall.width, settings.wall.height)) std::abort();
    try {
      const auto image =
          walls::decodeRegion(f, {0, 0, settings.wall.width, settings.wall.height}, 1, 0, 1);
      if (image.width != settings.wall.width || image.height != settings.wall.height) std::abort();
    } catch (const FormatError&) {
    }
    ++presented;
  });
  auto peer = std::make_unique<FuzzPeer>();
  core.attach(*peer);
  std::span rest(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  // After a peer is dropped, the next peer's bytes start at the next magic (a real sink hangs
  // up; searching instead of stepping byte by byte keeps each input cheap).
  auto skipToNextMessage = [&](std::size_t from) {
    const std::byte magic[4] = {std::byte{0x56}, std::byte{0x57}, std::byte{0x57}, std::byte{0x50}};
    const auto at = std::search(rest.begin() + std::ptrdiff_t(std::min(from, rest.size())),
                                rest.end(), magic, magic + 4);
    rest = rest.subspan(std::size_t(at - rest.begin()));
  };
  while (rest.size() >= net::kHeaderBytes) {
    const std::span<const std::byte, net::kHeaderBytes> header(rest.data(), net::kHeaderBytes);
    bool ok = true, consumed = false;
    try {
      net::MessageType type{};
      std::uint64_t frame = 0;
      const std::uint32_t length = net::checkHeader(header, peer->name(), &type, &frame);
      if (length > core.payloadLimit(*peer) || length > rest.size() - net::kHeaderBytes) {
        ok = false;
        skipToNextMessage(1);
      } else {
        const auto payload = rest.subspan(net::kHeaderBytes, length);
        rest = rest.subspan(net::kHeaderBytes + length);
        consumed = true;
        net::checkPayload(header, payload, peer->name());
        ok = core.handle(*peer, type, frame, payload) && !peer->hungUp;
      }
    } catch (const FormatError&) {
      core.dropped(*peer, "fuzz");
      ok = false;
      skipToNextMessage(consumed ? 0 : 1);
    }
    if (!ok) {
      core.detach(*peer);
      peer = std::make_unique<FuzzPeer>();
      core.attach(*peer);
    }
    if (core.assembler().heldBytes() > core.assembler().pendingBytesLimit()) std::abort();
  }
  core.detach(*peer);
  return 0;
}
