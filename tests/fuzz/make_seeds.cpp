// Writes every registered codec's sample files, and a series of steps of each codec's, as the
// fuzzer's seed corpus: make_seeds DIR
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
  for (const Codec* codec : codecs()) {
    const auto samples = codec->samples();
    for (const CodecSample& sample : samples)
      writeContainer(sample.volume, dir + "/" + sample.name + ".vwz");
    // A series of three steps: the first sample twice around the second where they agree in size
    // (sections every step has alike are shared), else the first three times.
    if (samples.empty()) continue;
    const CompressedVolume& first = samples.front().volume;
    const CompressedVolume& second = samples.size() > 1 ? samples[1].volume : first;
    const bool fits = second.info.dims == first.info.dims && second.info.type == first.info.type &&
                      second.info.spacing == first.info.spacing;
    try {
      writeContainer(makeSeries({first, fits ? second : first, first}),
                     dir + "/" + std::string(codec->name()) + "-series.vwz");
    } catch (const std::invalid_argument&) {
    }
  }
  return 0;
}
