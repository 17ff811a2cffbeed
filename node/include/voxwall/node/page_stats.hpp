// What a rank's decoded pages did in a frame: a plain struct, so the frame loop's messages carry
// it without the raycaster.
#pragma once

#include <cstdint>

namespace voxwall::node {

// A rank's decoded-page cache in a frame (TileStats): lane samples that found their page resident
// and that did not, pages decoded, pages evicted, bytes resident after the frame, and of the
// samples that missed, those taken from a coarser level (--lod-under-pressure) and those that
// waited for a page another thread was decoding; and the pages decoded ahead of the frame, before
// its rays came (RankRenderer::decodeAhead; not in `decoded`).
struct PageStats {
  std::uint64_t hits = 0, missed = 0, decoded = 0, evictions = 0, residentBytes = 0, coarse = 0;
  std::uint64_t waited = 0, ahead = 0;
};

}  // namespace voxwall::node
