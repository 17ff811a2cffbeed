// Frame preparation and the rendering backends (CPU threads, CUDA).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/node/camera.hpp>
#include <voxwall/node/cost_grid.hpp>
#include <voxwall/node/kernels/raycast.hpp>
#include <voxwall/node/render_volume.hpp>
#include <voxwall/node/transfer_function.hpp>

namespace voxwall::node {

// How a ray's steps composite (RenderSettings::preIntegrate), or may, where the march is picked
// from an error budget.
enum class MarchIntegration { Point, Pre, Either };

struct RenderSettings {
  double stepVoxels = 0.25;  // ray step in voxels (of the smallest spacing); Guthe & Goesele: 1/4
  // Each step composites the segment between two samples from pre-integrated tables (Engel,
  // Kraus and Ertl 2001; kernels::TransferLut) instead of the transfer function at one sample,
  // so that a step of a voxel misses no thin peak of the transfer function. False: the
  // fixed-step march of the point table (what --exact renders).
  bool preIntegrate = false;
  // > 0: the step and integration are picked from this budget (PSNR in dB against a converged
  // render) on the job's first view (chooseMarch, node/march_budget.hpp); the two above are then
  // what it picked. 0: as given.
  double errorBudgetDb = 0.0;
  MarchIntegration marchIntegration = MarchIntegration::Point;  // what the pick may use
  bool shading = false;  // Blinn-Phong from central-difference gradients
  // Gradients from the 24 voxels around each cell, blended per sample (the same gradient to
  // rounding), instead of six trilinear samples per shaded sample (the original, for comparison).
  bool cellGradients = true;
  bool emptySpaceSkipping = true;
  // Views with mip levels (svmm, ksvd): nearest-voxel samples instead of trilinear, and coarser
  // levels where a voxel is smaller than the pixel's footprint (level of detail).
  bool nearest = false;
  bool levelOfDetail = false;
  // Views with coarser levels (svmm, ksvd) on the CPU backend's decoded pages: a sample whose page
  // is not resident and would need an eviction reads level 1 instead, from pages of its own (a
  // quarter of the decode budget more); the pages are decoded after the tile
  // (node/page_cache.hpp).
  bool lodUnderPressure = false;
  // Rays on a lattice where the screen magnifies the volume (node/ray_lattice.hpp): the lattice's
  // side in pixels, a power of two up to kMaxLatticeStride; 0 picks it from the frame (half a
  // projected voxel, rounded down to a power of two); 1 casts a ray a pixel.
  int latticeStride = 0;
  // A lattice cell whose four corner rays differ by more than this (8-bit levels, in any channel)
  // is split and its rays cast at half the stride, down to a ray a pixel; the rest of its pixels
  // are interpolated from its corners.
  int refineAboveLevels = 8;
  int coarseCellFactor = 4;  // coarse skip cells are this many fine (codec range) cells per side
  double earlyTerminationOpacity = 0.995;
  int lutEntries = 4096;
};

// Everything a backend needs for one frame, built once on the host and shared by all tiles.
struct FramePlan {
  kernels::RayFrame ray;
  HostLut lut;
  // The skip grids (kernels::SkipGrid): coarse cells, a byte each, 1 = TF zero over the whole
  // cell; fine cells (the codec's range grid), a bit each, likewise. Shared, not copied, by the
  // plans that reuse them (planFrame's `reuse`): at 0.95 Gvox (cells of 4 voxels) the fine grid
  // is 1.9 MiB on every rank.
  std::shared_ptr<const std::vector<std::uint8_t>> emptyCells;
  std::shared_ptr<const std::vector<std::uint32_t>> fineEmptyBits;
  kernels::SkipGrid skip;          // points into the two vectors (host)
  double emptyFraction = 0.0;      // share of coarse cells skipped
  double fineEmptyFraction = 0.0;  // share of fine cells skipped
  bool lodUnderPressure = false;   // RenderSettings::lodUnderPressure
  // A pass that only decodes pages ahead of a frame (RankRenderer::decodeAhead): its pixels are
  // not used, and it evicts no decoded page (PageCache::setEvicting).
  bool decodeAhead = false;
  int latticeStride = 1;      // the ray lattice's side in pixels (1: a ray a pixel)
  int refineAboveLevels = 8;  // RenderSettings::refineAboveLevels
};

inline constexpr int kMaxLatticeStride = 16;

// The ray lattice's side for a frame (RenderSettings::latticeStride 0): the largest power of two,
// up to kMaxLatticeStride, no larger than half the pixels the volume's smallest voxel side spans
// at the volume's farthest corner from the eye (where it spans the fewest), so that a feature a
// voxel wide always falls on lattice rays. 1 where a voxel spans fewer than 4 pixels.
int autoLatticeStride(const codec::VolumeInfo& info, const Camera& camera, int screenHeight);

// `tfDomain` is the data-value range the LUT covers (usually the TF's own domain).
// Throws std::invalid_argument for a non-positive step or screen size.
// With `reuse` (a plan made for the same volume, transfer function and settings, e.g. the
// previous frame's), its transfer-function part (LUT, skip grids: most of the planning time on
// a large volume) is copied instead of rebuilt; only the camera part is new.
FramePlan planFrame(const RenderVolume& volume, const Camera& camera, int screenWidth,
                    int screenHeight, const TransferFunction& tf, const RenderSettings& settings,
                    const FramePlan* reuse = nullptr);

struct TileStats {
  double seconds = 0.0;
  std::uint64_t samples = 0;  // transfer-function samples taken (empty-space skips excluded)
  std::uint64_t rays = 0;     // rays cast (fewer than the pixels where a ray lattice interpolates)
  bool stopped = false;       // told to stop before every pixel was rendered
  // The CPU backend's decoded pages (node/page_cache.hpp) in this tile: lane samples that found
  // their page resident and that did not, pages decoded, pages evicted, and the bytes resident
  // after it; of the samples that missed, those taken from a coarser level (lod under pressure)
  // and those that waited for a page another thread was decoding; of the pages decoded, those
  // decoded into a thread's scratch page for one step, as no slot could be taken.
  std::uint64_t pageHits = 0, pageMissed = 0, pageDecoded = 0, pageEvictions = 0, pageCoarse = 0;
  std::uint64_t pageWaited = 0, pageScratch = 0, pageResidentBytes = 0;
};

enum class BackendKind { Cpu, Cuda };

// How the CUDA backend samples a compressed volume. Whole: decoded once on the host by its codec
// and uploaded as raw bricks (RenderVolume::decodedPayload) where those fit in the device's free
// memory; a GPU samples raw bricks one to two orders of magnitude faster than it decodes blocks
// per ray (docs/benchmarks.md). PerRay, and Whole where the bricks do not fit or the volume has
// no decoded form: the compressed bytes are uploaded and each ray decodes the blocks it reaches.
enum class DeviceDecode { Whole, PerRay };

// CUDA failures: the call, the error string and where.
class CudaError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Rays on a lattice of the virtual screen: point (i, j) is the ray through pixel (points.x + i *
// stride, points.y + j * stride); a point may lie past the screen's right or bottom edge (its ray
// goes on past the screen's edge). With `need` (points.width x points.height flags, row by row)
// only the points whose flag is set are traced.
struct RayPoints {
  Rect points;  // x, y: the first point's pixel; width, height: points per row and per column
  int stride = 1;
  const std::uint8_t* need = nullptr;
};

// Renders rectangles of the virtual screen. Not thread-safe: one frame at a time.
class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;
  // Renders `tile` of the virtual screen into `out` (resized to the tile). With `costs` (a grid
  // over the whole virtual screen), adds the time spent on each part of the tile to its cells:
  // the CPU backend per 16x16 block (thread-seconds), the CUDA backend spread over the tile.
  // Once `*stop` turns true (another thread sets it: the camera moved), the tile is left
  // unfinished as soon as the work in progress ends (the CPU backend: each thread's 16x16 block;
  // the CUDA backend: the kernel launched) and the stats say `stopped`.
  // Where the plan has a ray lattice (FramePlan::latticeStride > 1) and the backend traces
  // lattices, the tile's pixels come from it (node/ray_lattice.hpp): the same picture whatever the
  // tiles; otherwise a ray a pixel.
  TileStats render(const RenderVolume& volume, const FramePlan& plan, const Rect& tile, Image& out,
                   CostGrid* costs = nullptr, const std::atomic<bool>* stop = nullptr);

  // Whether renderPoints works (the CPU backend's; the CUDA backend casts a ray a pixel).
  virtual bool tracesLattices() const { return false; }
  // Host threads the backend renders on (what host-side work beside it may use too).
  virtual int hostThreads() const { return 1; }
  // Traces the lattice's rays into `out`, which is points.width x points.height already: the
  // points not needed keep what they held. With `costs`, as render(), over the pixels the points
  // stand for. Throws std::logic_error where tracesLattices() is false.
  virtual TileStats renderPoints(const RenderVolume& volume, const FramePlan& plan,
                                 const RayPoints& points, Image& out, CostGrid* costs,
                                 const std::atomic<bool>* stop);

 protected:
  virtual TileStats renderTile(const RenderVolume& volume, const FramePlan& plan, const Rect& tile,
                               Image& out, CostGrid* costs, const std::atomic<bool>* stop) = 0;
};

// threads: CPU worker threads (0 = all cores); decode: how a CUDA backend samples a compressed
// volume. Cuda throws CudaError when no device is usable.
std::unique_ptr<Backend> makeBackend(BackendKind kind, int threads = 0,
                                     DeviceDecode decode = DeviceDecode::Whole);
// packets: trace SIMD packets of neighbouring rays where the CPU has an instruction set the build
// compiled them for (AVX2, AVX-512); false, or no such set: one ray at a time (the same per-ray
// code, as CUDA runs it). Both give the same picture to rounding.
// decodeCacheBytes: with packets, a compressed volume (vq, svmm, ksvd, tvq, zfp) is sampled from
// pages of decoded voxels (node/page_cache.hpp), decoded as rays reach them and evicted when more
// than this many bytes would be held; 0 decodes bricks per ray, as without packets.
inline constexpr std::uint64_t kDefaultDecodeCacheBytes = std::uint64_t(512) << 20;
std::unique_ptr<Backend> makeCpuBackend(int threads, bool packets = true,
                                        std::uint64_t decodeCacheBytes = kDefaultDecodeCacheBytes);
// The decoded pages a CPU backend made for the last compressed volume it rendered: bytes resident
// now (pages, and the bricks they share for zfp: brick_memo.hpp), the bytes every page
// of the volume would take, the capacity (the pool's and the shared bricks') and a page's bytes
// (all 0: none), and the counts since they were made: lane samples that found their page
// resident and that did not, pages decoded into the pool, pages decoded into a lane's scratch page
// (no slot was free), pages evicted.
struct DecodeCacheUse {
  std::uint64_t bytes = 0, allPagesBytes = 0, capacityBytes = 0, pageBytes = 0;
  std::uint64_t hits = 0, missed = 0, misses = 0, scratch = 0, evictions = 0, coarse = 0;
  std::uint64_t coarseBytes = 0;  // resident in the pages of level 1 (--lod-under-pressure)
};
DecodeCacheUse cpuDecodeCacheUse(const Backend& backend);
// The most a CPU backend with packets holds in decoded pages for `volume` with this budget: every
// page of the volume, capped by the budget (0 for raw volumes, which need none).
std::uint64_t cpuDecodeCacheNeed(const RenderVolume& volume, std::uint64_t decodeCacheBytes);
// What --lod-under-pressure adds: level 1's pages (svmm, ksvd with levels), up to a quarter of the
// budget (0 for other volumes).
std::uint64_t cpuCoarsePageNeed(const RenderVolume& volume, std::uint64_t decodeCacheBytes);
// Rays per packet of the CPU backend on this CPU (1: none of the build's SIMD targets runs here).
std::size_t cpuPacketLanes();
// The SIMD targets the build compiled the packets for that this CPU runs, best first, by
// Highway's names ("AVX3", "AVX2", then the baseline, which traces one ray at a time). The CPU
// backend runs the best unless restricted to one of them: restrictCpuPacketTarget(name), for
// the whole process, until called with "" (tests and benchmarks). Throws std::invalid_argument
// for a name not in the list.
std::vector<std::string> cpuPacketTargets();
void restrictCpuPacketTarget(const std::string& name);
std::unique_ptr<Backend> makeCudaBackend(DeviceDecode decode = DeviceDecode::Whole);
// Whether the CUDA backend can run here; otherwise `reason` says why (not built, no device...).
bool cudaAvailable(std::string* reason = nullptr);

}  // namespace voxwall::node
