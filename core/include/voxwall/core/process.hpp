// What this process holds in memory, as the kernel counts it.
#pragma once

#include <cstddef>
#include <cstdint>

namespace voxwall {

struct ProcessMemory {
  std::uint64_t residentBytes = 0;  // now (VmRSS)
  std::uint64_t peakBytes = 0;      // the most since the process started (VmHWM)
  // Of residentBytes: the process's own (RssAnon: the heap, decoded pages, frame buffers), and
  // pages of mapped files (RssFile: a mapped .vwz, the libraries), which processes on one host
  // mapping the same file share and the system can drop and read again.
  std::uint64_t privateBytes = 0, fileBytes = 0;
  // This process's share of the shared memory it maps (Pss_Shmem: a page that n processes map
  // counts 1/n to each): the decode tables the ranks on one host make once for all of them
  // (codec/host_tables.hpp), an MPI library's shared buffers.
  std::uint64_t sharedBytes = 0;
};

// From /proc/self/status and /proc/self/smaps_rollup; zeros where the system has no such file.
ProcessMemory processMemory();

// Hands the allocator's free memory back to the system (glibc's malloc_trim: free pages inside
// its heaps and arenas too, which free() alone keeps for later allocations). Nothing elsewhere.
// For after a large structure was freed in pieces (a codec's decode tables), so that resident
// memory shows it.
void returnFreeMemory();

// From now on every block of `bytes` or more is a mapping of its own, handed back to the system
// when freed (glibc's M_MMAP_THRESHOLD; setting it also stops glibc moving that threshold and the
// trim threshold). Otherwise glibc raises the threshold to the largest block freed so far (up to
// 32 MiB), later blocks that size come from the heaps, and a thread's heap keeps them once freed
// when they lie at its top (malloc_trim does not shrink a thread's heap): a 0.95 Gvox tvq render
// held 23 MiB per rank, whatever its tile, of the slabs its volume's opening had freed. Nothing
// elsewhere. For a program's start, before its threads.
void mapLargeBlocksAlone(std::size_t bytes = std::size_t(1) << 20);

}  // namespace voxwall
