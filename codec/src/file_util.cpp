#include "file_util.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>

namespace voxwall::codec {

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
