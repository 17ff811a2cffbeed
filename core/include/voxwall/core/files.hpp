// Writing files so that a full disk, a write error or a killed process never leaves a partial
// file under its final name: bytes go to "<path>.tmp.<pid>" with every write(), fsync() and
// close() checked, and only a complete temporary is renamed into place.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace voxwall {

// Size and xxHash64 (seed 0) of a file's bytes: what a manifest records to verify it later.
struct FileDigest {
  std::uint64_t bytes = 0;
  std::uint64_t xxh64 = 0;
  bool operator==(const FileDigest&) const = default;
};
FileDigest digestOf(std::span<const std::byte> bytes);
// Reads the file and digests it; false when it cannot be read.
bool digestFile(const std::string& path, FileDigest* digest);
// A 64-bit value as 16 lower-case hex digits, as manifests and logs write hashes and ids.
std::string hex64(std::uint64_t value);
// Whether the file can be read and has this size and hash (as hex64 writes it).
bool fileHasDigest(const std::string& path, std::uint64_t bytes, const std::string& xxh64Hex);

// Writes `bytes` durably to the temporary name of `path` and returns that name. Throws
// FormatError naming `path` and the reason (e.g. "No space left on device"); nothing is left
// behind then.
std::string writeTemporary(const std::string& path, std::span<const std::byte> bytes);
// The same for a file written piece after piece (no copy of them joined).
std::string writeTemporary(const std::string& path,
                           std::span<const std::span<const std::byte>> pieces);
// Renames a finished temporary over `path` (or removes it and throws FormatError).
void commitTemporary(const std::string& temporary, const std::string& path);
// writeTemporary + commitTemporary.
void writeFileAtomically(const std::string& path, std::span<const std::byte> bytes);
// "<path>.tmp.<pid>": the temporary's name; the marker ".tmp." is what stale-file cleaners match.
std::string temporaryNameFor(const std::string& path);
// fsync()s a finished file; throws FormatError naming `path` (the file it will become).
void syncFile(const std::string& file, const std::string& path);

}  // namespace voxwall
