// Stands in for cuda_backend.cu in builds without CUDA (VOXWALL_CUDA=OFF).
#include <voxwall/node/renderer.hpp>

namespace voxwall::node {

bool cudaAvailable(std::string* reason) {
  if (reason) *reason = "this build has no CUDA backend (configured with VOXWALL_CUDA=OFF)";
  return false;
}

std::unique_ptr<Backend> makeCudaBackend(DeviceDecode) {
  throw CudaError("this build has no CUDA backend (configured with VOXWALL_CUDA=OFF)");
}

}  // namespace voxwall::node
