// The CUDA backend against the CPU backend. Skips (reported as skipped, not passed) without a
// usable device, and in builds without CUDA.
#include <gtest/gtest.h>

#include <optional>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/image_expect.hpp"

using namespace voxwall;
using namespace voxwall::node;

class BackendEquivalence : public ::testing::TestWithParam<codec::ScalarType> {};

TEST_P(BackendEquivalence, CudaMatchesCpu) {
  std::string reason;
  if (!cudaAvailable(&reason)) GTEST_SKIP() << reason;
  const auto volume = RenderVolume::fromVolume(codec::generateSheppLogan(64, GetParam()), 8);
  Orbit o;
  const Camera cam = orbitCamera(o, boundingRadius(volume.info()));
  const auto tf =
      TransferFunction::preset("ct-soft").rescaled(volume.info().valueMin, volume.info().valueMax);
  for (bool shading : {false, true}) {
    RenderSettings s;
    s.shading = shading;
    const auto plan = planFrame(volume, cam, 96, 64, tf, s);
    Image cpu, gpu;
    const Rect tile{8, 4, 80, 56};
    const auto cpuStats = makeCpuBackend(2)->render(volume, plan, tile, cpu);
    const auto gpuStats = makeCudaBackend()->render(volume, plan, tile, gpu);
    // Same per-ray code; fused multiply-adds on the device may move a sample across a rounding
    // edge.
    test::expectImagesNear(cpu, gpu, 3, 45.0, shading ? "shaded" : "unshaded");
    EXPECT_NEAR(double(gpuStats.samples), double(cpuStats.samples),
                0.01 * double(cpuStats.samples));
  }
}

INSTANTIATE_TEST_SUITE_P(ScalarTypes, BackendEquivalence,
                         ::testing::Values(codec::ScalarType::UInt8, codec::ScalarType::UInt16,
                                           codec::ScalarType::Float32),
                         [](const auto& info) {
                           return std::string(codec::scalarName(info.param));
                         });

// Every registered codec's view (each of its sample files that can be rendered) on the device
// against the CPU: the same per-ray code through the payload's device view and arrays, and
// through the raw bricks of the volume decoded whole.
TEST(BackendEquivalence, EveryCodecsViewMatchesTheCpu) {
  std::string reason;
  if (!cudaAvailable(&reason)) GTEST_SKIP() << reason;
  auto perRay = makeCudaBackend(DeviceDecode::PerRay), whole = makeCudaBackend();
  int rendered = 0, decoded = 0;
  for (const codec::Codec* c : codec::codecs())
    for (codec::CodecSample& sample : c->samples()) {
      SCOPED_TRACE(sample.name);
      std::optional<RenderVolume> volume;
      try {
        volume = RenderVolume::fromCompressed(std::move(sample.volume));
      } catch (const FormatError&) {
        continue;  // a file the codec holds but cannot render (RGBA svmm)
      }
      Orbit o;
      const Camera cam = orbitCamera(o, boundingRadius(volume->info()));
      const auto tf = TransferFunction::preset("ct-soft").rescaled(volume->info().valueMin,
                                                                   volume->info().valueMax);
      for (bool shading : {false, true}) {
        RenderSettings s;
        s.shading = shading;
        const auto plan = planFrame(*volume, cam, 64, 48, tf, s);
        Image cpu, gpu, gpuWhole;
        const Rect tile{0, 0, 64, 48};
        makeCpuBackend(2)->render(*volume, plan, tile, cpu);
        perRay->render(*volume, plan, tile, gpu);
        whole->render(*volume, plan, tile, gpuWhole);
        test::expectImagesNear(cpu, gpu, 3, 45.0, sample.name + (shading ? " shaded" : ""));
        test::expectImagesNear(cpu, gpuWhole, 3, 45.0,
                               sample.name + (shading ? " shaded" : "") + " decoded whole");
      }
      ++rendered;
      decoded += volume->decodedPayload() != nullptr;
    }
  EXPECT_GE(rendered, int(codec::codecs().size()));
  EXPECT_GE(decoded, int(codec::codecs().size()) - 1);  // all but raw's
}

TEST(CudaBackend, WithoutADeviceItRefusesWithAReason) {
  std::string reason;
  if (cudaAvailable(&reason)) GTEST_SKIP() << "a device is present";
  EXPECT_FALSE(reason.empty());
  EXPECT_THROW(makeCudaBackend(), CudaError);
}
