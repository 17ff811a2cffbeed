// Image assertions that leave evidence: on failure the baseline, the rendered image and a diff
// are written to <build>/tests/output/<test>-{baseline,rendered,diff}.png.
#pragma once

#include <string>
#include <voxwall/core/image.hpp>

namespace voxwall::test {

// Expects every channel within maxAbs (0 = identical) and, when minPsnrDb > 0, PSNR above it.
void expectImagesNear(const voxwall::Image& baseline, const voxwall::Image& rendered, int maxAbs,
                      double minPsnrDb = 0.0, const std::string& label = "");

}  // namespace voxwall::test
