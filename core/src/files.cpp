#include <fcntl.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>

namespace voxwall {

std::string temporaryNameFor(const std::string& path) {
  return path + ".tmp." + std::to_string(::getpid());
}

FileDigest digestOf(std::span<const std::byte> bytes) {
  return {bytes.size(), XXH64(bytes.data(), bytes.size(), 0)};
}

bool digestFile(const std::string& path, FileDigest* digest) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  XXH64_state_t* state = XXH64_createState();
  XXH64_reset(state, 0);
  std::uint64_t total = 0;
  std::byte buffer[1 << 16];
  bool ok = true;
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) ok = false;
    if (n <= 0) break;
    XXH64_update(state, buffer, std::size_t(n));
    total += std::uint64_t(n);
  }
  ::close(fd);
  if (ok) *digest = {total, XXH64_digest(state)};
  XXH64_freeState(state);
  return ok;
}

std::string hex64(std::uint64_t value) {
  char text[20];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

bool fileHasDigest(const std::string& path, std::uint64_t bytes, const std::string& xxh64Hex) {
  FileDigest digest;
  return digestFile(path, &digest) && digest.bytes == bytes && hex64(digest.xxh64) == xxh64Hex;
}

std::string writeTemporary(const std::string& path,
                           std::span<const std::span<const std::byte>> pieces) {
  const std::string tmp = temporaryNameFor(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw FormatError(path, std::string("cannot create: ") + std::strerror(errno));
  auto fail = [&](int err) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw FormatError(path, std::string("cannot write: ") + std::strerror(err));
  };
  for (const std::span<const std::byte> bytes : pieces) {
    const std::byte* p = bytes.data();
    std::size_t left = bytes.size();
    while (left > 0) {
      const ssize_t n = ::write(fd, p, std::min<std::size_t>(left, 1 << 24));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail(n < 0 ? errno : ENOSPC);
      p += n, left -= std::size_t(n);
    }
  }
  // Delayed allocation reports a full disk only here (or at close) on some filesystems.
  if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) fail(errno);
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw FormatError(path, std::string("cannot write: ") + std::strerror(err));
  }
  return tmp;
}

std::string writeTemporary(const std::string& path, std::span<const std::byte> bytes) {
  const std::span<const std::byte> pieces[] = {bytes};
  return writeTemporary(path, pieces);
}

void syncFile(const std::string& file, const std::string& path) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw FormatError(path, std::string("cannot write: ") + std::strerror(errno));
  const bool synced = ::fsync(fd) == 0 || errno == EINVAL || errno == EROFS;
  const int err = errno;
  ::close(fd);
  if (!synced) throw FormatError(path, std::string("cannot write: ") + std::strerror(err));
}

void commitTemporary(const std::string& temporary, const std::string& path) {
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const int err = errno;
    std::remove(temporary.c_str());
    throw FormatError(path, std::string("cannot write: ") + std::strerror(err));
  }
}

void writeFileAtomically(const std::string& path, std::span<const std::byte> bytes) {
  commitTemporary(writeTemporary(path, bytes), path);
}

}  // namespace voxwall
