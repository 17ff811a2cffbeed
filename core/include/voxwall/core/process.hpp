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

// Hands the allocator's free memory back to the system (glibc's malloc_trim: free pages inside
// its heaps and arenas too, which free() alone keeps for later allocations). Nothing elsewhere.
// For after a large structure was freed in pieces (a codec's decode tables), so that resident
// memory shows it.
void returnFreeMemory();

}  // namespace voxwall
