// `voxwall render`'s options and what they mean: the command line as a plain struct, and pure
// functions from it to the job's and the renderer's settings (unit-tested in
// tests/master/render_settings_test.cpp). The orchestration is in render.cpp.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>
#include <voxwall/codec/codec.hpp>
#include <voxwall/master/render_job.hpp>
#include <voxwall/node/march_budget.hpp>
#include <voxwall/node/renderer.hpp>

#include "../cli_common.hpp"
#include "option_checks.hpp"

namespace voxwall::cli {

struct RenderOptions {
  std::string input, size = "1920x1080", tf = "mri", tfRange, camera = "30,20,2.6", out = "frames";
  std::string backend = "cpu", background = "black", format = "png", tiles = "1x1";
  std::string deviceDecode = "whole";  // --device-decode
  std::string path = "orbit", balance = "dynamic", memoryBudget, pan, view;
  std::string sink, token, wall, subsampling = "420", tileCodec = "jpeg";
  int surface = 0;      // of a multi-surface Tide configuration
  std::string opacity;  // --opacity: the opacity curve of another map
  std::string window;   // --window CENTER,WIDTH (level/width)
  std::string rescale;  // --rescale SLOPE,INTERCEPT: stored values to the map's units
  int jpegQuality = 90;
  int interactiveStep = 4;       // --interactive-step
  std::string refine = "4,2,1";  // --refine
  double frameBudgetMs = 200;    // --frame-budget
  double settle = 0.5;           // --settle, seconds
  double sinkDeadline = 30;      // --sink-deadline, seconds
  bool sizeGiven = false, outGiven = false, framesGiven = false;
  bool interactiveStepGiven = false, frameBudgetGiven = false;
  std::string time;              // --time A:B[:S], A, or all
  double timeRate = 0;           // --time-rate STEPS_PER_SECOND (on the wall)
  std::string range = "series";  // --range series|per-step: what the transfer function spans
  double fov = 30, orbitDeg = 0, zoomTo = 1.2, watchdogSeconds = 120;
  std::string step = "auto";                         // --step auto|VOXELS
  double errorBudget = node::kDefaultErrorBudgetDb;  // --error-budget DB (--step auto)
  int frames = 1, threads = 0, costCell = 32;
  std::string sampling = "trilinear", gradients = "cell";
  std::string simd = "on";           // --simd: the CPU backend's ray packets
  std::string decodeCache = "512M";  // --decode-cache: decoded pages of a brick-coded volume
  bool lod = false;
  bool lodUnderPressure = false;     // --lod-under-pressure
  std::string lattice = "auto";      // --lattice auto|1|2|4|8|16: the ray lattice's side in pixels
  int refineAbove = 8;               // --refine-above LEVELS
  bool exact = false;                // --exact: a ray a pixel
  std::string integration = "auto";  // --integration auto|pre|point
  // Render flags of the codecs (Codec::renderOptions, e.g. tvq's --progressive) as given.
  std::map<std::string, std::string> codecFlags;
  bool shading = false, noSkip = false, noWrite = false, quiet = false, verbose = false;
  bool balanceGiven = false, masterOnly = false, dryRun = false, resume = false;
  RawInputOptions raw;
};

// Registers every render option with `cmd`; the callback must call noteGiven() before use.
struct RenderOptionHandles {
  CLI::Option *balance = nullptr, *size = nullptr, *out = nullptr, *frames = nullptr;
  CLI::Option *interactiveStep = nullptr, *frameBudget = nullptr;
  void noteGiven(RenderOptions& o) const {
    o.interactiveStepGiven = interactiveStep->count() > 0;
    o.frameBudgetGiven = frameBudget->count() > 0;
    o.framesGiven = frames->count() > 0;
    o.balanceGiven = balance->count() > 0;
    o.sizeGiven = size->count() > 0;
    o.outGiven = out->count() > 0;
  }
};
RenderOptionHandles addRenderOptions(CLI::App& cmd, RenderOptions& o);

// The job: screen (--size or --wall), sink, camera path, output, cut and watchdog. Reads the wall
// and key-frame files it names; throws std::invalid_argument naming the option.
master::JobSettings jobSettings(const RenderOptions& o);
// --time and --time-rate for a volume of `steps` time steps: which steps the frames show. Throws
// std::invalid_argument naming the option for a range outside the volume's steps.
master::TimeSettings timeSettings(const RenderOptions& o, int steps);
// The renderer: step, shading, skipping, sampling, level of detail.
node::RenderSettings renderSettings(const RenderOptions& o);

// The transfer function as --tf, --opacity, --tf-range, --window, --rescale and --range ask,
// checked once (the maps themselves are loaded where the volume's values are known).
struct TransferSettings {
  std::string map = "mri", opacity;                // presets or files (FILE, FILE:NAME)
  std::optional<std::pair<double, double>> range;  // --tf-range or --window, the map's units
  double slope = 1, intercept = 0;                 // --rescale: stored values to the map's
  bool perStep = false;                            // --range per-step (else series)
};
TransferSettings transferSettings(const RenderOptions& o);

// The rank's backend and its memory, as --backend, --threads, --simd, --decode-cache,
// --device-decode and --memory-budget ask.
struct BackendSettings {
  node::BackendKind kind = node::BackendKind::Cpu;
  int threads = 0;                     // 0: the host's cores shared by its ranks
  bool simd = true;                    // CPU: packets of rays
  std::uint64_t decodeCacheBytes = 0;  // CPU with packets: decoded pages (0: off)
  node::DeviceDecode deviceDecode = node::DeviceDecode::Whole;  // CUDA, compressed volumes
  std::optional<std::uint64_t> memoryBudgetBytes;               // refuse to start above this
  // Whether a rank decodes pages of a brick-coded volume (node/page_cache.hpp).
  bool decodesPages() const {
    return kind == node::BackendKind::Cpu && simd && decodeCacheBytes > 0;
  }
};
BackendSettings backendSettings(const RenderOptions& o);
// The codec render flags given (--progressive ...), for RenderVolume::open.
codec::CodecOptionValues codecRenderOptions(const RenderOptions& o);

// --background: none/transparent, black, white or R,G,B in [0, 1].
std::optional<glm::dvec3> parseBackground(const std::string& text);
// Memory a rank needs for this job (docs/distributed.md): `volumeBytes` is what the rank holds of
// the volume (the compressed file and, on a CPU rank, its decoded pages at most).
std::uint64_t estimateRankBytes(const master::JobSettings& job, int rank, int ranks,
                                std::uint64_t volumeBytes, std::uint64_t baseBytes);
// "WxH+X+Y", and a list of them each after a space.
std::string rectText(const voxwall::Rect& r);
std::string rectList(const std::vector<voxwall::Rect>& rects);
// The job manifest rank 0 stores with the frames (--resume compares it).
std::string manifest(const RenderOptions& o, const master::JobSettings& job,
                     const node::RenderSettings& render, std::uint64_t fingerprint);

}  // namespace voxwall::cli
