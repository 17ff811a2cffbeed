// Writes every registered codec's sample files as the fuzzer's seed corpus: make_seeds DIR
#include <cstdio>
#include <filesystem>
#include <string>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/registry.hpp>

int main(int argc, char** argv) {
  using namespace voxwall::codec;
  if (argc != 2) {
    std::fprintf(stderr, "usage: vwz_make_seeds DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    std::fprintf(stderr, "vwz_make_seeds: %s: %s\n", dir.c_str(), ec.message().c_str());
    return 1;
  }
  for (const Codec* codec : codecs())
    for (const CodecSample& sample : codec->samples())
      writeContainer(sample.volume, dir + "/" + sample.name + ".vwz");
  return 0;
}
