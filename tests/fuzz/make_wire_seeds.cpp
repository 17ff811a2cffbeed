// Writes one valid message of every type into DIR, as seeds for wire_fuzz.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <voxwall/net/wire.hpp>

using namespace voxwall;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_wire_seeds DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    std::fprintf(stderr, "make_wire_seeds: %s: %s\n", dir.c_str(), ec.message().c_str());
    return 1;
  }
  voxwall::Image image(16, 8);
  for (auto& p : image.pixels) p = 0xff336699u;
  std::vector<std::vector<std::byte>> seeds = {
      net::encodeMessage(net::Hello{net::Role::Renderer, 1, 4, "ci-2x2", "token"}),
      net::encodeMessage(
          net::Welcome{"ci-2x2", 196, 132, {{0, 0, 96, 64}, {100, 0, 96, 64}}, false}),
      net::encodeMessage(3, net::FrameEnd{1, 4}),
      net::encodeMessage(net::Control{net::ControlCommand::Rotate, 10, -5}),
      net::encodeMessage(net::Bye{"done"}),
      net::encodeMessage(4, net::FrameNote{net::FrameStatus::Dropped, "too many frames open"}),
      net::encodeMessage(net::Control{net::ControlCommand::Seek, 12, 0}),
      net::encodeMessage(5, net::Playback{3, 1, 9, 2, true, 4}),
  };
  for (auto codec : {net::TileCodec::Jpeg, net::TileCodec::Raw, net::TileCodec::Deflate}) {
    net::TileCodecSettings s;
    s.codec = codec;
    const auto t = net::encodeTiles(image, {4, 4, 16, 8}, {0, 0, 0}, s)[0];
    seeds.push_back(net::encodeMessage(7, net::TileMessage{t.rect, t.codec, 1, t.bytes}));
  }
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    std::ofstream out(dir + "/seed" + std::to_string(i), std::ios::binary);
    out.put(char(0));  // first byte: where the fuzzer cuts the stream
    out.write(reinterpret_cast<const char*>(seeds[i].data()), std::streamsize(seeds[i].size()));
  }
  return 0;
}
