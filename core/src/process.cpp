#include <cstring>
#include <fstream>
#include <string>
#include <voxwall/core/process.hpp>

namespace voxwall {

ProcessMemory processMemory() {
  std::ifstream in("/proc/self/status");
  std::string line;
  ProcessMemory m;
  while (std::getline(in, line)) {
    auto value = [&](const char* key, std::uint64_t& out) {
      if (line.rfind(key, 0) == 0) out = std::stoull(line.substr(std::strlen(key))) * 1024;
    };
    value("VmRSS:", m.residentBytes);
    value("VmHWM:", m.peakBytes);
  }
  return m;
}

}  // namespace voxwall
