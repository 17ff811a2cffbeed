#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <vector>
#include <voxwall/node/march_budget.hpp>

namespace voxwall::node {

void probeScreen(int screenWidth, int screenHeight, int& probeWidth, int& probeHeight) {
  if (screenWidth <= 0 || screenHeight <= 0)
    throw std::invalid_argument("screen size must be positive");
  constexpr double kPixels = 96000.0;
  const double scale =
      std::min(1.0, std::sqrt(kPixels / (double(screenWidth) * double(screenHeight))));
  probeWidth = std::max(1, int(std::lround(screenWidth * scale)));
  probeHeight = std::max(1, int(std::lround(screenHeight * scale)));
}

MarchChoice chooseMarch(Backend& backend, const RenderVolume& volume, const Camera& camera,
                        int screenWidth, int screenHeight, const TransferFunction& tf,
                        RenderSettings settings, double budgetDb) {
  MarchChoice choice;
  probeScreen(screenWidth, screenHeight, choice.probeWidth, choice.probeHeight);
  const Rect all{0, 0, choice.probeWidth, choice.probeHeight};
  const auto start = std::chrono::steady_clock::now();
  settings.latticeStride = 1;
  auto render = [&](double step, bool pre) {
    settings.stepVoxels = step;
    settings.preIntegrate = pre;
    const FramePlan plan =
        planFrame(volume, camera, choice.probeWidth, choice.probeHeight, tf, settings);
    Image image;
    backend.render(volume, plan, all, image);
    return image;
  };
  const Image reference = render(0.125, false);
  const MarchIntegration may = settings.marchIntegration;
  std::vector<bool> integrations;
  if (may != MarchIntegration::Pre) integrations.push_back(false);
  if (may != MarchIntegration::Point) integrations.push_back(true);
  choice.stepVoxels = 0.25, choice.preIntegrate = may == MarchIntegration::Pre;
  for (const double step : {1.0, 0.75, 0.5, 0.375}) {
    bool found = false;
    for (const bool pre : integrations) {
      ++choice.marchesTried;
      const double psnr = compareImages(render(step, pre), reference).psnrDb;
      if (psnr >= budgetDb + kMarchMarginDb) {
        choice.stepVoxels = step, choice.preIntegrate = pre, choice.probePsnrDb = psnr;
        found = true;
        break;
      }
    }
    if (found) break;
  }
  if (choice.probePsnrDb == 0.0)
    choice.probePsnrDb = compareImages(render(0.25, choice.preIntegrate), reference).psnrDb;
  choice.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return choice;
}

}  // namespace voxwall::node
