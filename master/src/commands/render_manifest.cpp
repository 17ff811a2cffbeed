// The job manifest (voxwall-job.json beside the frames): what a render is, for --resume to
// check that the frames on disk are of the same job.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <utility>
#include <voxwall/node/transfer_function.hpp>

#include "render_settings.hpp"

namespace voxwall::cli {

std::string manifest(const RenderOptions& o, const master::JobSettings& job,
                     const node::RenderSettings& render, std::uint64_t fingerprint) {
  char hex[32];
  std::snprintf(hex, sizeof hex, "%016llx", (unsigned long long)fingerprint);
  nlohmann::json m;
  m["voxwall_job"] = 1;
  m["volume_fingerprint"] = hex;
  m["size"] = {job.width, job.height};
  m["wall"] = o.wall;
  m["surface"] = o.surface;
  m["frames"] = job.frames;
  m["time"] = {job.time.first, job.time.last, job.time.stride};
  m["range"] = o.range;
  m["path"] = o.path;
  m["camera"] = o.camera;
  m["view"] = o.view;
  m["fov"] = o.fov;
  m["pan"] = o.pan;
  m["orbit_deg"] = o.orbitDeg;
  m["zoom_to"] = o.zoomTo;
  m["tf"] = o.tf;
  m["tf_range"] = o.tfRange;
  m["window"] = o.window;
  m["rescale"] = o.rescale;
  m["opacity"] = o.opacity;
  // With --step auto the march is picked from the budget on the job's first view (the same
  // pick for the same settings): the budget is what the job is.
  if (render.errorBudgetDb > 0) {
    m["step"] = "auto";
    m["error_budget"] = render.errorBudgetDb;
  } else {
    m["step"] = render.stepVoxels;
  }
  if (render.marchIntegration != node::MarchIntegration::Point)
    m["integration"] = render.marchIntegration == node::MarchIntegration::Pre ? "pre" : "auto";
  m["shading"] = render.shading;
  if (!render.cellGradients) m["gradients"] = "samples";
  if (render.nearest) m["sampling"] = "nearest";
  if (render.levelOfDetail) m["lod"] = true;
  if (render.lodUnderPressure) m["lod_under_pressure"] = true;
  m["lattice"] = render.latticeStride;  // 0: picked per frame
  if (render.latticeStride != 1) m["refine_above"] = render.refineAboveLevels;
  for (const auto& [flag, value] : o.codecFlags) m["codec_options"][flag] = value;
  m["format"] = job.format;
  m["background"] = o.background;
  m["backend"] = o.backend;  // CUDA and CPU may differ in the last bit of a channel
  // Files named by the settings count by their contents: an edited file is another render.
  for (auto [key, file] : {std::pair{"path_file", o.path}, std::pair{"tf_file", o.tf},
                           std::pair{"opacity_file", o.opacity}}) {
    // FILE:NAME names a map in FILE.
    if (key != std::string("path_file")) file = node::TransferFunction::splitSpec(file).file;
    if (!std::filesystem::is_regular_file(file)) continue;
    std::ifstream in(file, std::ios::binary);
    m[key] = std::string(std::istreambuf_iterator<char>(in), {});
  }
  return m.dump();
}

}  // namespace voxwall::cli
