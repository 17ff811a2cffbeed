// Writes the DICOM reader fuzzer's seeds: make_dicom_seeds DIR. Each seed is a folder's files
// joined by "\nSPLIT\n" (dicom_reader_fuzz.cpp): a small CT series, compressed slices, a
// multi-frame file, an enhanced MR of two images, a time series of slices, an enhanced file of
// two time points.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "support/dicom_writer.hpp"

namespace {

namespace fs = std::filesystem;
using namespace voxwall::test;

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

DicomSlice seedSlice(int k, DicomSyntax syntax) {
  DicomSlice s;
  s.columns = 6, s.rows = 5;
  for (int i = 0; i < 30; ++i) s.pixels.push_back(std::int16_t(i * 7 + k * 3 - 20));
  s.position = {0, 0, 2.0 * k};
  s.slope = 2, s.intercept = -1024;
  s.syntax = syntax;
  return s;
}

// Series of three slices in each transfer syntax, a multi-frame file and a time series of
// slices: two positions, two time points told apart by trigger time and instance, and an echo
// time (an image key) on every slice.
void writeSliceSeeds(const fs::path& dir, const std::string& scratch) {
  const std::pair<const char*, DicomSyntax> series[] = {{"explicit", DicomSyntax::ExplicitLittle},
                                                        {"rle", DicomSyntax::Rle},
                                                        {"jpegls", DicomSyntax::JpegLs},
                                                        {"jpeg", DicomSyntax::JpegLossless},
                                                        {"implicit", DicomSyntax::ImplicitLittle}};
  for (const auto& [name, syntax] : series) {
    std::string joined;
    for (int k = 0; k < 3; ++k) {
      writeDicom(scratch, seedSlice(k, syntax));
      joined += (k ? "\nSPLIT\n" : "") + slurp(scratch);
    }
    std::ofstream(dir / name, std::ios::binary) << joined;
  }
  DicomSlice multi = seedSlice(0, DicomSyntax::ExplicitLittle);
  multi.frames = 2, multi.isUnsigned = true, multi.slope = 1;
  multi.pixels.clear();
  for (int i = 0; i < 60; ++i) multi.pixels.push_back(std::int16_t(i));
  writeDicom(scratch, multi);
  std::ofstream(dir / "multiframe", std::ios::binary) << slurp(scratch);
  std::string steps;
  for (int k = 0; k < 4; ++k) {
    DicomSlice s = seedSlice(k % 2, DicomSyntax::ExplicitLittle);
    s.modality = "MR", s.instance = k + 1, s.triggerTime = 40.0 * (k / 2), s.echoTime = 12;
    writeDicom(scratch, s);
    steps += (k ? "\nSPLIT\n" : "") + slurp(scratch);
  }
  std::ofstream(dir / "timeseries", std::ios::binary) << steps;
}

// An enhanced MR of two images (frame types, a rescale each) at two positions, geometry in the
// functional groups only; and the same frames as two time points of one image.
void writeEnhancedSeeds(const fs::path& dir, const std::string& scratch) {
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
  for (EnhancedFrame& f : enhanced.frames) f.temporalIndex = f.imageIndex, f.imageIndex = 1;
  writeEnhancedDicom(scratch, enhanced);
  std::ofstream(dir / "enhanced-time", std::ios::binary) << slurp(scratch);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_dicom_seeds DIR\n");
    return 2;
  }
  const fs::path dir = argv[1];
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    std::fprintf(stderr, "make_dicom_seeds: %s: %s\n", argv[1], ec.message().c_str());
    return 1;
  }
  const std::string scratch = (dir / "scratch.dcm").string();
  writeSliceSeeds(dir, scratch);
  writeEnhancedSeeds(dir, scratch);
  fs::remove(scratch);
  return 0;
}
