// Writes every registered codec's sample files, a series of steps of each codec's, and a series
// each codec coded as one (encodeSeries: a model shared by the steps where the codec keeps one),
// as the fuzzer's seed corpus: make_seeds DIR
#include <cstdio>
#include <filesystem>
#include <string>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/codec/series_source.hpp>
#include <voxwall/codec/volume_io.hpp>

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
  // Three small steps, the first again last (so that a codebook shared by the steps pays even
  // lossless), as files a SeriesSource reads.
  std::vector<SeriesSource::Step> steps;
  for (int k = 0; k < 3; ++k) {
    const std::string file = dir + "/step" + std::to_string(k) + ".nrrd";
    writeVolume(generateOrbitingBlobs(12, k % 2, 2), file);
    steps.push_back({file, file, 0, SeriesSource::Kind::File});
  }
  const SeriesSource series(steps, {});
  voxwall::Progress quiet;
  for (const Codec* codec : codecs()) {
    try {
      std::string report;
      writeContainer(codec->encodeSeries(series, {}, quiet, report),
                     dir + "/" + std::string(codec->name()) + "-coded-series.vwz");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "vwz_make_seeds: %s series: %s\n", std::string(codec->name()).c_str(),
                   e.what());
    }
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
  for (const auto& step : steps) std::filesystem::remove(step.file, ec);
  return 0;
}
