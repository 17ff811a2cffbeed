// Writes the DICOM reader fuzzer's seeds: make_dicom_seeds DIR. Each seed is a folder's files
// joined by "\nSPLIT\n" (dicom_reader_fuzz.cpp): a small CT series, compressed slices, a
// multi-frame file, an enhanced MR of two images.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "support/dicom_writer.hpp"

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

int main(int argc, char** argv) {
  using namespace voxwall::test;
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_dicom_seeds DIR\n");
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    std::fprintf(stderr, "make_dicom_seeds: %s: %s\n", argv[1], ec.message().c_str());
    return 1;
  }
  const std::string scratch = (dir / "scratch.dcm").string();
  auto slice = [](int k, DicomSyntax syntax) {
    DicomSlice s;
    s.columns = 6, s.rows = 5;
    for (int i = 0; i < 30; ++i) s.pixels.push_back(std::int16_t(i * 7 + k * 3 - 20));
    s.position = {0, 0, 2.0 * k};
    s.slope = 2, s.intercept = -1024;
    s.syntax = syntax;
    return s;
  };
  const std::pair<const char*, DicomSyntax> series[] = {{"explicit", DicomSyntax::ExplicitLittle},
                                                        {"rle", DicomSyntax::Rle},
                                                        {"jpegls", DicomSyntax::JpegLs},
                                                        {"jpeg", DicomSyntax::JpegLossless},
                                                        {"implicit", DicomSyntax::ImplicitLittle}};
  for (const auto& [name, syntax] : series) {
    std::string joined;
    for (int k = 0; k < 3; ++k) {
      writeDicom(scratch, slice(k, syntax));
      joined += (k ? "\nSPLIT\n" : "") + slurp(scratch);
    }
    std::ofstream(dir / name, std::ios::binary) << joined;
  }
  DicomSlice multi = slice(0, DicomSyntax::ExplicitLittle);
  multi.frames = 2, multi.isUnsigned = true, multi.slope = 1;
  multi.pixels.clear();
  for (int i = 0; i < 60; ++i) multi.pixels.push_back(std::int16_t(i));
  writeDicom(scratch, multi);
  std::ofstream(dir / "multiframe", std::ios::binary) << slurp(scratch);
  // An enhanced MR of two images (frame types, a rescale each) at two positions, geometry in
  // the functional groups only.
  EnhancedImage enhanced;
  enhanced.columns = 6, enhanced.rows = 5;
  enhanced.pixelSpacing = {0.8, 0.9};
  for (std::uint32_t image = 1; image <= 2; ++image)
    for (std::uint32_t z = 1; z <= 2; ++z) {
      EnhancedFrame f;
      f.position = {0, 0, 3.0 * z};
      f.imageIndex = image, f.stackPosition = z;
      if (image == 2) f.frameType = "ORIGINAL\\PRIMARY\\B0_MAP\\NONE", f.slope = 0.5;
      for (int i = 0; i < 30; ++i) f.pixels.push_back(std::int16_t(i * int(z) - 7));
      enhanced.frames.push_back(f);
    }
  writeEnhancedDicom(scratch, enhanced);
  std::ofstream(dir / "enhanced", std::ios::binary) << slurp(scratch);
  std::filesystem::remove(scratch);
  return 0;
}
