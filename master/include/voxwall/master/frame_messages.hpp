// Messages of the distributed frame loop, exchanged between the master (rank 0) and the
// rendering ranks. They travel over MPI (master/), but are plain bytes here so they can be
// tested and fuzzed without MPI.
//
// Message sequence, for every frame f (collective over all ranks):
//   master  --FrameTask{f, camera, rects of every rank}-->  every rank   (broadcast)
//   every rank renders its rects
//   every rank  --RankReport{f, time, pixels, cost grid}-->  master      (gather)
// and at the end a FrameTask with `stop` set, after which every rank sends its final RankReport
// (no pixels; resident memory) and leaves the loop.
//
// Layout (little-endian, serialized field by field):
//   FrameTask:  u32 magic 'VWFT', u32 version, u32 frame, u32 flags (bit 0: stop, bit 1: an
//               interactive frame, bit 2: a refining frame; neither: a full one; bit 3: the
//               next frame's camera and time step follow the time step),
//               u64 decidedUnixMicros, u64 jobId, f64 eye[3], center[3], up[3], fovYDeg, u32
//               watchdogMs, i32 screenWidth, screenHeight, i32 cellPixels, i32 step, u32
//               timeStep, (bit 3) f64 eye[3], center[3], up[3], fovYDeg, u32 timeStep of the
//               next frame, u32 rankCount, per rank: u32 rectCount, then i32 x, y, width, height
//               per rect.
//   RankReport: u32 magic 'VWRR', u32 version, u32 frame, i32 rank, f64 renderSeconds,
//               u64 samples, u64 residentBytes, u64 peakResidentBytes, u64 privateBytes,
//               u64 fileBytes, u64 sharedBytes, u64 pageHits, pageMissed, pageDecoded,
//               pageEvictions, pageResidentBytes, pageCoarse, pageWaited, pageAhead, u64 rays, i32
//               latticeStride, u32 flags (bit 0: pixels included, bit 1: streamed to the sink, bit
//               2: the sink refused this rank for good, bit 3: the rank abandoned the frame), f64
//               encodeSeconds, u64 streamedBytes, u16 length + bytes of streamError, u32 tileCount,
//               per tile: i32 x, y, width, height, then (with pixels) width*height u32 RGBA8, then
//               i32 cellsX, cellsY (0, 0: no grid), i32 cx0, cy0, cw, ch (the cells under this
//               rank's tiles) and cw*ch f64 seconds, row by row.
#pragma once

#include <cstdint>
#include <span>
#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/net/wire.hpp>
#include <voxwall/node/camera.hpp>
#include <voxwall/node/cost_grid.hpp>
#include <voxwall/node/page_stats.hpp>

namespace voxwall::master {

inline constexpr std::uint32_t kFrameTaskMagic = 0x54465756;   // "VWFT"
inline constexpr std::uint32_t kRankReportMagic = 0x52525756;  // "VWRR"
// 2: FrameTask.jobId; 3: no tfVersion; 4: FrameTask.step; 5: FrameTask's phase,
// RankReport.abandoned; 6: RankReport.pages; 7: RankReport.pages.coarse; 8: FrameTask.timeStep;
// 9: RankReport.rays and latticeStride.
inline constexpr std::uint32_t kFrameMessageVersion = 11;
// Limits a decoder enforces before it allocates anything.
inline constexpr int kMaxRanks = 1 << 16;
inline constexpr int kMaxRectsPerRank = 1 << 12;
inline constexpr int kMaxScreenSide = 1 << 16;
inline constexpr std::size_t kMaxStreamError = 256;
inline constexpr int kMaxTaskStep = 16;  // the same bound as the wall protocol's (wire.hpp)
inline constexpr std::uint32_t kMaxTimeSteps = 1u << 16;  // the same as a .vwz file's steps

struct FrameTask {
  std::uint32_t frame = 0;
  bool stop = false;                    // no more frames: send the final report and leave the loop
  std::uint64_t decidedUnixMicros = 0;  // when rank 0 decided the camera (for latency)
  std::uint64_t jobId = 0;  // the render job's identity on the wall sink (net/wire.hpp Hello)
  node::Camera camera;
  std::uint32_t watchdogMs = 0;  // how long any rank waits for any other in this frame
  int screenWidth = 0, screenHeight = 0;
  int cellPixels = 32;  // cost grid cell size
  // 1: a full frame. n > 1: an interactive frame, rendered at 1/n per side: screenWidth and
  // screenHeight (and the rects) are then the reduced screen, ceil(virtual side / n).
  int step = 1;
  net::FramePhase phase = net::FramePhase::Full;  // why it has that step (the sink shows it)
  std::uint32_t timeStep = 0;  // the volume's time step the frame shows (0 for one volume)
  // Where the job's path goes next (a batch job's next frame: unless the wall steers it, what
  // the next task will say), for decoding its pages ahead (RankRenderer::decodeAhead).
  bool ahead = false;
  node::Camera aheadCamera;
  std::uint32_t aheadTimeStep = 0;
  std::vector<std::vector<voxwall::Rect>> rects;  // per rank (index = rank); may be empty
};

struct RenderedTile {
  voxwall::Rect rect;
  voxwall::Image image;  // rect.width x rect.height, premultiplied RGBA8; empty without pixels
};

using PageStats = node::PageStats;  // a rank's decoded pages in a frame

struct RankReport {
  std::uint32_t frame = 0;
  int rank = 0;
  double renderSeconds = 0;  // wall time for all of this rank's rects
  std::uint64_t samples = 0;
  std::uint64_t rays = 0;  // rays cast (fewer than the pixels where the ray lattice interpolates)
  int latticeStride = 0;   // the frame's ray lattice (1: a ray a pixel; 0: nothing rendered)
  std::uint64_t residentBytes = 0, peakResidentBytes = 0;
  // Of residentBytes: the rank's own memory and its mapped files'; its share of the memory the
  // ranks on its host share (ProcessMemory).
  std::uint64_t privateBytes = 0, fileBytes = 0, sharedBytes = 0;
  PageStats pages;
  bool pixels = true;        // tiles carry their pixels (rank 0 writes frames)
  bool streamed = false;     // the tiles went to the wall sink
  double encodeSeconds = 0;  // compressing tiles for the sink
  std::uint64_t streamedBytes = 0;
  std::string streamError;  // why the tiles did not reach the sink (at most kMaxStreamError bytes)
  bool streamRefused = false;  // the sink refused this rank for good (token, wall, job, version)
  // Rank 0 abandoned the frame while this rank rendered it (the camera moved): its tiles are
  // not all rendered, and its costs are partial.
  bool abandoned = false;
  std::vector<RenderedTile> tiles;
  // Over the whole screen; only the cells under `tiles` travel (the rest decode as zero).
  // Empty (cellsX = 0) when not measured.
  node::CostGrid costs;
};

std::vector<std::byte> encode(const FrameTask& task);
std::vector<std::byte> encode(const RankReport& report);
// Decoders check magic, version, every count and every rectangle against the limits and the
// screen before allocating; they throw FormatError("<source>: ...") naming what is wrong.
FrameTask decodeFrameTask(std::span<const std::byte> bytes, const std::string& source);
// `task` is the frame the report answers: tiles must lie on its screen, the grid must match it.
RankReport decodeRankReport(std::span<const std::byte> bytes, const FrameTask& task,
                            const std::string& source);

}  // namespace voxwall::master
