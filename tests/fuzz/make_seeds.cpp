// Writes a few valid .vwz files as the fuzzer's seed corpus: make_seeds DIR
#include <cstdio>
#include <filesystem>
#include <string>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/vq_codec.hpp>

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
  Progress quiet;
  writeContainer(raw::encode(generateMenger(1), {4}, quiet), dir + "/menger1.vwz");
  writeContainer(raw::encode(generateMarschnerLobb(5, ScalarType::Float32), {4}, quiet),
                 dir + "/ml5.vwz");
  writeContainer(raw::encode(generateSheppLogan(6, ScalarType::Int16), {8}, quiet),
                 dir + "/sl6.vwz");
  vq::Params lossy;
  lossy.reduction = 2;
  vq::Params plain;
  plain.compressedCodebook = false;
  writeContainer(vq::encode(generateSheppLogan(7, ScalarType::Int16), {}, quiet), dir + "/vq7.vwz");
  writeContainer(vq::encode(generateMarschnerLobb(9), lossy, quiet), dir + "/vq9-lossy.vwz");
  writeContainer(vq::encode(generateMenger(2), plain, quiet), dir + "/vq-plain.vwz");
  svmm::Params tree;
  tree.blockWidth = 2, tree.rootWidth = 2;
  svmm::Params stepped;
  stepped.stepped = true, stepped.rootWidth = 4, stepped.quality = 80,
  stepped.baseCompression = true;
  writeContainer(svmm::encode(generateSheppLogan(9), tree, quiet), dir + "/svmm9.vwz");
  writeContainer(svmm::encode(generateSheppLogan(11, ScalarType::Int16), stepped, quiet),
                 dir + "/svmm11-stepped.vwz");
  writeContainer(svmm::encodeRgba(svmm::generateMengerRgba(2), tree, quiet),
                 dir + "/svmm-rgba.vwz");
  return 0;
}
