#include "file_util.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <voxwall/codec/errors.hpp>

namespace voxwall::codec {

std::string temporaryNameFor(const std::string& path) {
  return path + ".tmp." + std::to_string(::getpid());
}

void commitTemporary(const std::string& temporary, const std::string& path) {
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const int err = errno;
    std::remove(temporary.c_str());
    throw FormatError(path, std::string("cannot write: ") + std::strerror(err));
  }
}

void writeFileAtomically(const std::string& path, std::span<const std::byte> bytes) {
  const std::string tmp = temporaryNameFor(path);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw FormatError(path, std::string("cannot create: ") + std::strerror(errno));
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      throw FormatError(path, "write failed (disk full?)");
    }
  }
  commitTemporary(tmp, path);
}

std::string extensionOf(const std::string& path) {
  std::string name = std::filesystem::path(path).filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  bool gz = false;
  if (name.size() > 3 && name.ends_with(".gz")) {
    gz = true;
    name.resize(name.size() - 3);
  }
  const auto dot = name.rfind('.');
  std::string ext = dot == std::string::npos ? "" : name.substr(dot + 1);
  return gz ? (ext.empty() ? "gz" : ext + ".gz") : ext;
}

}  // namespace voxwall::codec
