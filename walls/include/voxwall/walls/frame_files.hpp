// A presented frame on disk, all or nothing: every display's picture
// (frame_NNNNN_<display>.png, and frame_NNNNN_mosaic.png for the whole virtual screen) is encoded
// and written under a temporary name first, then all are renamed into place, and last the
// frame's marker frame_NNNNN.done (JSON: each file's size and xxHash64) is written. A frame
// without its marker is not complete: a sink killed while writing leaves at most such files,
// and removeIncompleteFrames() clears them when the next sink starts on the folder.
#pragma once

#include <cstdint>
#include <string>
#include <voxwall/core/image.hpp>
#include <voxwall/walls/wall.hpp>

namespace voxwall::walls {

std::string frameStem(std::uint64_t frame);  // "frame_00012"
std::string frameMarkerPath(const std::string& dir, std::uint64_t frame);

// Writes one frame as above. Throws FormatError naming the file and the reason (e.g. "No space
// left on device"); nothing of the frame stays under a final name then.
void writeFrameFiles(const std::string& dir, std::uint64_t frame, const Wall& wall,
                     const voxwall::Image& screen, bool mosaic);

// Whether the frame's marker is there and every file it lists has its recorded size and hash.
bool frameFilesComplete(const std::string& dir, std::uint64_t frame);

// Removes temporaries (".tmp.") and the pictures of frames without a marker. Returns how many
// files it removed.
int removeIncompleteFrames(const std::string& dir);

}  // namespace voxwall::walls
