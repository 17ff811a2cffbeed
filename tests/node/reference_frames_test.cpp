// Every codec's frame against a reference frame kept from before the raycaster's speed work
// (tests/data/reference/, written by this test at commit 9551bad, before cell gradients): the
// picture must stay the same, shaded and unshaded. The compressed files are kept beside the
// frames, so an encoder change cannot move the reference; the raw volume is the generator's.
//
// VOXWALL_WRITE_REFERENCE=DIR writes the frames into DIR instead of comparing.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <voxwall/codec/generators.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"
#include "support/orbit_render.hpp"

using namespace voxwall;
using namespace voxwall::node;

namespace {

const std::string kDir = std::string(VOXWALL_TEST_DATA_DIR) + "/reference/";

RenderVolume phantom(const std::string& codec) {
  if (codec == "raw") return RenderVolume::fromVolume(codec::generateSheppLogan(64), 16);
  return RenderVolume::open(kDir + "phantom64_" + codec + ".vwz");
}

void checkAgainstReference(const std::string& codec) {
  const RenderVolume volume = phantom(codec);
  const auto tf = TransferFunction::preset("ct-soft").rescaled(0, 255);
  for (bool shading : {false, true}) {
    SCOPED_TRACE(codec + (shading ? " shaded" : " unshaded"));
    // Over black, as the wall shows it: the files are opaque and keep the colours exactly.
    Image frame = test::renderOrbit(volume, 160, 120, tf, shading);
    for (auto& p : frame.pixels) p |= 0xFF000000u;
    const std::string name = "phantom64_" + codec + (shading ? "_shaded" : "") + ".png";
    if (const char* out = std::getenv("VOXWALL_WRITE_REFERENCE")) {
      writeImage(frame, std::string(out) + "/" + name, glm::dvec3(0.0));
      continue;
    }
    // The bar for "the same picture" is 45 dB; most pixels are identical.
    const Image reference = readImage(kDir + name);
    const ImageDiff d = compareImages(reference, frame);
    std::printf("%s: PSNR %.1f dB, max difference %d\n", name.c_str(), d.psnrDb, d.maxAbs);
    test::expectImagesNear(reference, frame, 255, 45.0, name);
  }
}

}  // namespace

TEST(ReferenceFrames, Raw) { checkAgainstReference("raw"); }
TEST(ReferenceFrames, Vq) { checkAgainstReference("vq"); }
TEST(ReferenceFrames, Svmm) { checkAgainstReference("svmm"); }
TEST(ReferenceFrames, Ksvd) { checkAgainstReference("ksvd"); }
