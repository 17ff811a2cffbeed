// What this process holds in memory, as the kernel counts it.
#pragma once

#include <cstdint>

namespace voxwall {

struct ProcessMemory {
  std::uint64_t residentBytes = 0;  // now (VmRSS)
  std::uint64_t peakBytes = 0;      // the most since the process started (VmHWM)
};

// From /proc/self/status; zeros where the system has no such file.
ProcessMemory processMemory();

}  // namespace voxwall
