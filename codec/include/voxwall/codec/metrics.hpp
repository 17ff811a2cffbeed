// Quality metrics for codecs.
#pragma once

#include <cstdio>
#include <string>
#include <voxwall/codec/volume.hpp>

namespace voxwall::codec {

// Peak signal-to-noise ratio in dB of `test` against `reference`, with the peak being the
// reference's value range (valueMax - valueMin, or the type's range when that is 0).
// Returns +infinity for identical volumes. Throws std::invalid_argument on a dims mismatch.
double psnr(const Volume& reference, const Volume& test);

// Bits per voxel of a compressed size.
inline double bitsPerVoxel(std::uint64_t bytes, const Volume& v) {
  return v.voxelCount() ? 8.0 * double(bytes) / double(v.voxelCount()) : 0.0;
}

// A byte count for people: "512 B", "7.7 MiB".
std::string humanBytes(double bytes);

// printf-style formatting of a report line (at most 511 characters).
template <class... Args>
std::string formatLine(const char* format, Args... args) {
  char line[512];
  std::snprintf(line, sizeof line, format, args...);
  return line;
}

}  // namespace voxwall::codec
