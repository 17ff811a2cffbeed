// libFuzzer target: arbitrary bytes as a folder of DICOM files, through the DICOM reader (GDCM's
// scanner and decoders wrapped by codec/src/io/dicom.cpp). The input is cut at each "\nSPLIT\n"
// into up to four files of one folder, so that a series of several slices can be mutated.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/errors.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace fs = std::filesystem;
  static const fs::path dir =
      fs::temp_directory_path() / ("voxwall-dicom-fuzz-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  constexpr std::string_view kSplit = "\nSPLIT\n";
  std::size_t start = 0;
  for (int i = 0; i < 4 && start <= input.size(); ++i) {
    const std::size_t cut = i == 3 ? std::string_view::npos : input.find(kSplit, start);
    const std::string_view part =
        input.substr(start, cut == std::string_view::npos ? cut : cut - start);
    std::ofstream(dir / ("IM" + std::to_string(i)), std::ios::binary)
        .write(part.data(), std::streamsize(part.size()));
    if (cut == std::string_view::npos) break;
    start = cut + kSplit.size();
  }
  try {
    voxwall::codec::DicomOptions options;
    options.resampleTilt = size % 2 == 1;
    options.image = int(size % 3);  // none, the first or the second image of a series
    options.warn = [](const std::string&) {};
    (void)voxwall::codec::listDicomImages(dir.string(), options);
    // Every time step of the picked image (one for a series whose positions do not repeat).
    const voxwall::codec::DicomInput series(dir.string(), options);
    for (int k = 0; k < series.steps(); ++k) (void)series.read(k);
  } catch (const voxwall::FormatError&) {
  }
  return 0;
}
