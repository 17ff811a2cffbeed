// Writes seeds for sink_fuzz into DIR: a greeted renderer sending whole frames, a controller,
// a second job taking over, bad tiles. First byte: the settings byte sink_fuzz reads.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <voxwall/net/wire.hpp>

using namespace voxwall;

namespace {

std::vector<std::byte> tile(std::uint64_t frame, voxwall::Rect rect, net::TileCodec codec) {
  voxwall::Image image(rect.width, rect.height);
  for (auto& p : image.pixels) p = 0xff336699u;
  net::TileCodecSettings s;
  s.codec = codec;
  const auto t = net::encodeTiles(image, rect, {0, 0, 0}, s)[0];
  return net::encodeMessage(frame, net::TileMessage{t.rect, t.codec, 1, t.bytes});
}

void append(std::vector<std::byte>& out, const std::vector<std::byte>& m) {
  out.insert(out.end(), m.begin(), m.end());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_sink_seeds DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    std::fprintf(stderr, "make_sink_seeds: %s: %s\n", dir.c_str(), ec.message().c_str());
    return 1;
  }
  net::Hello renderer{net::Role::Renderer, 0, 2, "", ""};
  renderer.jobId = 7;
  net::Hello controller = renderer;
  controller.role = net::Role::Controller;
  std::vector<std::vector<std::byte>> seeds;
  for (std::uint8_t settings : {0, 1}) {
    const voxwall::Rect whole =
        settings & 1 ? voxwall::Rect{0, 0, 64, 48} : voxwall::Rect{0, 0, 84, 62};
    for (auto codec : {net::TileCodec::Raw, net::TileCodec::Jpeg, net::TileCodec::Deflate}) {
      std::vector<std::byte> s{std::byte{settings}};
      append(s, net::encodeMessage(renderer));
      for (std::uint64_t f = 0; f < 3; ++f) {
        append(s, tile(f, {0, 0, whole.width / 2, whole.height}, codec));
        append(s,
               tile(f, {whole.width / 2, 0, whole.width - whole.width / 2, whole.height}, codec));
        append(s, net::encodeMessage(f, net::FrameEnd{0, 2}));
      }
      seeds.push_back(s);
    }
    std::vector<std::byte> jobs{std::byte{settings}};
    append(jobs, net::encodeMessage(controller));
    append(jobs, net::encodeMessage(2, net::Playback{2, 0, 5, 1, false, 0}));
    append(jobs, tile(5, whole, net::TileCodec::Raw));  // a controller may not send tiles
    renderer.jobId = 8;
    append(jobs, net::encodeMessage(renderer));
    append(jobs, tile(~std::uint64_t(0), whole, net::TileCodec::Raw));
    append(jobs, tile(1, whole, net::TileCodec::Raw));
    append(jobs, net::encodeMessage(net::Bye{"done"}));
    renderer.jobId = 7;
    seeds.push_back(jobs);
  }
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    std::ofstream out(dir + "/seed" + std::to_string(i), std::ios::binary);
    out.write(reinterpret_cast<const char*>(seeds[i].data()), std::streamsize(seeds[i].size()));
  }
  return 0;
}
