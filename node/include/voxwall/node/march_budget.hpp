// The ray's march picked from an error budget: the longest step (and whether it is
// pre-integrated) whose picture of the job's first view stays within the budget of a converged
// render, measured on a probe of that view.
#pragma once

#include <voxwall/node/renderer.hpp>

namespace voxwall::node {

// PSNR in dB, over the four 8-bit channels, against a converged render (a ray a pixel at a
// 1/8-voxel step) that a frame by default stays above: below what the tiles' own JPEG costs
// (about 55 dB at quality 90).
inline constexpr double kDefaultErrorBudgetDb = 50.0;
// What a march's probe must beat the budget by: room for the ray lattice's own error and for a
// view other than the probe's.
inline constexpr double kMarchMarginDb = 3.0;

struct MarchChoice {
  double stepVoxels = 0.25;
  bool preIntegrate = false;
  double probePsnrDb = 0.0;  // the chosen march's probe against the probe's converged render
  int probeWidth = 0, probeHeight = 0;
  int marchesTried = 0;
  double seconds = 0.0;  // all the probes' rendering
};

// The virtual screen a probe renders: the frame's camera on a screen of at most about 96,000
// pixels (its aspect kept), so that its rays are a sparse sample of the frame's.
void probeScreen(int screenWidth, int screenHeight, int& probeWidth, int& probeHeight);

// Renders the view on the probe screen converged and with each march from the longest step down
// (1, 3/4, 1/2, 3/8 voxels, each at points and then pre-integrated, as
// settings.marchIntegration allows), and returns the first whose PSNR against the converged
// render is at least budgetDb + kMarchMarginDb; 1/4 voxel (at points, as --exact renders, unless
// only pre-integration is allowed) when none is. `settings` gives everything else (shading,
// skipping, ...); its step, integration and lattice are the probe's own. The choice depends only on
// the view, the volume, the transfer function and the settings, never on the backend's threads:
// every rank that makes it makes the same one.
MarchChoice chooseMarch(Backend& backend, const RenderVolume& volume, const Camera& camera,
                        int screenWidth, int screenHeight, const TransferFunction& tf,
                        RenderSettings settings, double budgetDb);

}  // namespace voxwall::node
