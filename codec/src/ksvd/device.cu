// COVRA's two-phase brick decompressor on a CUDA device (ksvd_device.hpp; Gobbetti, Iglesias
// Guitian and Marton, 2012, section 5.2). The two phases themselves are KsvdDecoder::pairOf and
// voxelOf (kernels/ksvd_view.hpp, tested on the CPU); this file maps them to threads, shared
// memory and a barrier. Compiled whenever nvcc is present; its test compares it with
// decompressBricks on the host and skips without a device.
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>
#include <voxwall/codec/ksvd_device.hpp>

#include "bricks.hpp"

namespace voxwall::codec::ksvd {
namespace {

void check(cudaError_t error, const char* what) {
  if (error != cudaSuccess)
    throw std::runtime_error(std::string("ksvd device decompression: ") + what + ": " +
                             cudaGetErrorString(error));
}

// Device memory owned by one object.
struct DeviceMemory {
  void* ptr = nullptr;
  explicit DeviceMemory(std::size_t bytes) {
    check(cudaMalloc(&ptr, bytes ? bytes : 1), "cudaMalloc");
  }
  DeviceMemory(const DeviceMemory&) = delete;
  DeviceMemory& operator=(const DeviceMemory&) = delete;
  ~DeviceMemory() { cudaFree(ptr); }
};

// One brick to decompress, as the kernel reads it.
struct Job {
  int level, bx, by, bz;
};

constexpr int kThreads = 128;
constexpr int kMaxPairs = 255;  // S <= 255 (the file's limit)

// One CUDA block per K-SVD block: blockIdx.x = job * N^3 + j, block j of the job's brick.
template <int Side>
__global__ void twoPhaseKernel(kernels::KsvdView<Side> view, const Job* jobs, float* out) {
  constexpr int kVoxels = Side * Side * Side;
  __shared__ int atom[kMaxPairs];
  __shared__ float coefficient[kMaxPairs];
  const int n = view.level[0].decoder.blocksPerBrick;
  const int perBrick = n * n * n, side = n * Side;
  const int jobIndex = int(blockIdx.x) / perBrick, j = int(blockIdx.x) % perBrick;
  const Job job = jobs[jobIndex];
  const auto& level = view.level[job.level];
  const auto& d = level.decoder;
  const int lx = j % n, ly = (j / n) % n, lz = j / (n * n);
  const int bx = job.bx * n + lx, by = job.by * n + ly, bz = job.bz * n + lz;
  const int blocksZ = (level.dimZ + Side - 1) / Side;
  float* brick =
      out + std::size_t(jobIndex) * std::size_t(side) * std::size_t(side) * std::size_t(side);
  auto at = [&](int v) {
    const int x = v % Side, y = (v / Side) % Side, z = v / (Side * Side);
    return (std::size_t(lz * Side + z) * std::size_t(side) + std::size_t(ly * Side + y)) *
               std::size_t(side) +
           std::size_t(lx * Side + x);
  };
  if (bx >= d.blocksX || by >= d.blocksY || bz >= blocksZ) {  // past the level's edge
    for (int v = int(threadIdx.x); v < kVoxels; v += int(blockDim.x)) brick[at(v)] = 0.0f;
    return;
  }
  const auto code = d.locate(d.key(bx, by, bz));
  // Phase 1: the block's pairs to shared memory.
  for (int t = int(threadIdx.x); t < code.count; t += int(blockDim.x))
    d.pairOf(code, t, atom[t], coefficient[t]);
  __syncthreads();
  // Phase 2: each thread its voxels (0 past the level's edge: the encoder's padding).
  for (int v = int(threadIdx.x); v < kVoxels; v += int(blockDim.x)) {
    const int x = bx * Side + v % Side, y = by * Side + (v / Side) % Side,
              z = bz * Side + v / (Side * Side);
    const bool inside = x < level.dimX && y < level.dimY && z < level.dimZ;
    brick[at(v)] = inside ? d.voxelOf(code, atom, coefficient, v) : 0.0f;
  }
}

}  // namespace

bool deviceDecompressionAvailable(std::string* reason) {
  int count = 0;
  const cudaError_t error = cudaGetDeviceCount(&count);
  if (error != cudaSuccess || count == 0) {
    if (reason)
      *reason = error != cudaSuccess
                    ? std::string("no usable CUDA device: ") + cudaGetErrorString(error)
                    : std::string("no CUDA device");
    return false;
  }
  return true;
}

std::vector<float> decompressBricksOnDevice(const Layout& layout,
                                            std::span<const BrickRef> bricks) {
  std::vector<Job> jobs;
  for (const BrickRef& b : bricks) {
    checkBrick(layout, b);
    jobs.push_back({b.level, b.brick.x, b.brick.y, b.brick.z});
  }
  std::string reason;
  if (!deviceDecompressionAvailable(&reason))
    throw std::runtime_error("ksvd device decompression: " + reason);
  const int m = layout.blockSide(), n = blocksPerBrick(m);
  const std::size_t brickVoxels = std::size_t(n * m) * std::size_t(n * m) * std::size_t(n * m);
  std::vector<float> out(bricks.size() * brickVoxels);
  if (bricks.empty()) return out;
  const auto bytes = layout.joinedBytes();
  DeviceMemory data(bytes.size()), jobMemory(jobs.size() * sizeof(Job)),
      outMemory(out.size() * sizeof(float));
  check(cudaMemcpy(data.ptr, bytes.data(), bytes.size(), cudaMemcpyHostToDevice), "upload");
  check(cudaMemcpy(jobMemory.ptr, jobs.data(), jobs.size() * sizeof(Job), cudaMemcpyHostToDevice),
        "upload");
  const unsigned grid = unsigned(jobs.size()) * unsigned(n * n * n);
  layout.withView(
      [&](const auto& view) {
        constexpr int Side = std::decay_t<decltype(view)>::Level::kSide;
        twoPhaseKernel<Side><<<grid, kThreads>>>(view, static_cast<const Job*>(jobMemory.ptr),
                                                 static_cast<float*>(outMemory.ptr));
      },
      static_cast<const std::byte*>(data.ptr));
  check(cudaGetLastError(), "launch");
  check(cudaMemcpy(out.data(), outMemory.ptr, out.size() * sizeof(float), cudaMemcpyDeviceToHost),
        "download");
  return out;
}

}  // namespace voxwall::codec::ksvd
