#include <cstring>
#include <fstream>
#include <string>
#include <voxwall/core/process.hpp>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

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
    value("RssAnon:", m.privateBytes);
    value("RssFile:", m.fileBytes);
  }
  std::ifstream rollup("/proc/self/smaps_rollup");
  while (std::getline(rollup, line))
    if (line.rfind("Pss_Shmem:", 0) == 0) m.sharedBytes = std::stoull(line.substr(10)) * 1024;
  return m;
}

void returnFreeMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

void mapLargeBlocksAlone(std::size_t bytes) {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, int(bytes));
#else
  (void)bytes;
#endif
}

}  // namespace voxwall
