// Pieces shared by the voxwall subcommands: option parsing, volume input, progress bars.
#pragma once

#include <CLI/CLI.hpp>
#include <map>
#include <optional>
#include <string>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/metrics.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::cli {

// Options that say what an input file does not say about itself (the layout of a headerless raw
// file, the series of a DICOM folder), attached to any command that reads volumes.
struct RawInputOptions {
  std::string dims, type = "uint8", spacing;
  bool bigEndian = false;
  std::uint64_t headerBytes = 0;
  std::string series;
  bool resampleTilt = false;
  int dicomImage = 0;       // --dicom-image N
  std::string orientation;  // --orientation letters, e.g. "RAS"
  void addTo(CLI::App& app);
  // The layout when --dims was given; throws std::invalid_argument on malformed values.
  std::optional<codec::RawLayout> layout() const;
  // The layout and the DICOM options together.
  codec::ReadOptions readOptions() const;
  // Applies --spacing and --orientation, which override what the file says; throws
  // std::invalid_argument on malformed values.
  void applyOverrides(codec::Volume& volume) const;
  void applyOverrides(codec::VolumeSource& source) const;
};

// "X,Y,Z" with positive integers / positive reals; "WxH". Throw std::invalid_argument naming
// the option.
glm::ivec3 parseDims(const std::string& text, const std::string& option);
glm::dvec3 parseSpacing(const std::string& text, const std::string& option);
std::pair<int, int> parseSize(const std::string& text, const std::string& option);
std::vector<double> parseNumbers(const std::string& text, const std::string& option);

// Reads a volume named on the command line: a file, a directory of slices, or
// "generated:<menger|marschner-lobb|shepp-logan>:<size or level>".
codec::Volume loadVolume(const std::string& spec, const codec::ReadOptions& options);

// Registers on `cmd` the flags every registered codec declares for it (`list`: Codec::options for
// compress, Codec::renderOptions for render), each flag once (help texts joined where codecs share
// a flag). `given` receives each flag given, with its value ("1" for a flag that takes none).
void addCodecFlags(CLI::App& cmd, std::vector<codec::CodecOption> (codec::Codec::*list)() const,
                   std::map<std::string, std::string>& given);

// Prints a progress bar on stderr when it is a terminal, one line per stage otherwise.
voxwall::Progress makeProgress(bool quiet);

// Thrown by a rank other than rank 0 when the job fails for a reason rank 0 reports: main exits
// with status 1 without printing, so the user reads one line, not one per rank.
struct SilentFailure : std::exception {
  const char* what() const noexcept override { return "failure reported by rank 0"; }
};

// Whether an MPI launcher started this process as a rank other than 0 (from its environment,
// before MPI is initialised): such a rank keeps quiet about errors every rank sees.
bool isNonZeroRank();

}  // namespace voxwall::cli
