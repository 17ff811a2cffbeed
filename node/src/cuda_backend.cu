// The CUDA backend: uploads the compressed volume once, the transfer-function table and the
// skip grid per frame, and launches one thread per pixel running the same raycastPixel as the
// CPU backend. Only allocation, upload, launch and download live here (docs/architecture.md).
#include <cuda_runtime.h>

#include <bit>
#include <chrono>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>
#include <voxwall/node/renderer.hpp>

#define VOXWALL_CUDA_CHECK(call) ::voxwall::node::cudaCheck((call), #call, __FILE__, __LINE__)

namespace voxwall::node {
namespace {

void cudaCheck(cudaError_t error, const char* call, const char* file, int line) {
  if (error != cudaSuccess)
    throw CudaError(std::string(call) + ": " + cudaGetErrorString(error) + " (" + file + ":" +
                    std::to_string(line) + ")");
}

// Device memory owned by one object; grows, never shrinks.
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  ~DeviceBuffer() {
    if (ptr_) cudaFree(ptr_);
  }
  void reserve(std::size_t bytes) {
    if (bytes <= capacity_) return;
    if (ptr_) VOXWALL_CUDA_CHECK(cudaFree(ptr_));
    ptr_ = nullptr;
    capacity_ = 0;
    VOXWALL_CUDA_CHECK(cudaMalloc(&ptr_, bytes ? bytes : 1));
    capacity_ = bytes;
  }
  void upload(const void* src, std::size_t bytes) {
    reserve(bytes);
    if (bytes) VOXWALL_CUDA_CHECK(cudaMemcpy(ptr_, src, bytes, cudaMemcpyHostToDevice));
  }
  template <class T>
  T* as() const {
    return static_cast<T*>(ptr_);
  }

 private:
  void* ptr_ = nullptr;
  std::size_t capacity_ = 0;
};

// SVMM block pools (thesis section 3.3): every level but the root (and a block-compressed base)
// as a 3D array of blocks read through a texture object, or, when the pool is larger than the
// device's 3D texture limit, as linear device memory in the same layout.
class SvmmPools {
 public:
  SvmmPools() = default;
  SvmmPools(const SvmmPools&) = delete;
  SvmmPools& operator=(const SvmmPools&) = delete;
  ~SvmmPools() { release(); }

  // Builds the pools for `layout` unless they were built for it already.
  void build(const codec::svmm::Layout& layout, const cudaDeviceProp& prop) {
    if (&layout == builtFor_) return;
    release();
    levels_.assign(std::size_t(layout.levels()), Level{});
    for (int L = 0; L < layout.levels(); ++L) {
      if (!layout.poolable(L)) continue;
      const auto shape = layout.poolShape(L);
      const int wl = std::countr_zero(unsigned(layout.widths()[std::size_t(L)]));
      const std::size_t eb = std::size_t(layout.elementBytes(L));
      const std::size_t width = std::size_t(1) << (shape.uLog2 + wl);
      const std::size_t height = std::size_t(1) << (shape.vLog2 + wl);
      const std::size_t depth = std::size_t(shape.w) << wl;
      std::vector<std::uint8_t> bytes = layout.poolBytes(L);
      Level& level = levels_[std::size_t(L)];
      level.uLog2 = shape.uLog2, level.vLog2 = shape.vLog2;
      if (width <= std::size_t(prop.maxTexture3D[0]) &&
          height <= std::size_t(prop.maxTexture3D[1]) &&
          depth <= std::size_t(prop.maxTexture3D[2])) {
        const cudaChannelFormatDesc desc = eb == 1   ? cudaCreateChannelDesc<unsigned char>()
                                           : eb == 2 ? cudaCreateChannelDesc<unsigned short>()
                                                     : cudaCreateChannelDesc<unsigned int>();
        const cudaExtent extent = make_cudaExtent(width, height, depth);
        VOXWALL_CUDA_CHECK(cudaMalloc3DArray(&level.array, &desc, extent));
        cudaMemcpy3DParms copy{};
        copy.srcPtr = make_cudaPitchedPtr(bytes.data(), width * eb, width, height);
        copy.dstArray = level.array;
        copy.extent = extent;
        copy.kind = cudaMemcpyHostToDevice;
        VOXWALL_CUDA_CHECK(cudaMemcpy3D(&copy));
        cudaResourceDesc resource{};
        resource.resType = cudaResourceTypeArray;
        resource.res.array.array = level.array;
        cudaTextureDesc texture{};
        for (int a = 0; a < 3; ++a) texture.addressMode[a] = cudaAddressModeClamp;
        texture.filterMode = cudaFilterModePoint;
        texture.readMode = cudaReadModeElementType;
        texture.normalizedCoords = 0;
        VOXWALL_CUDA_CHECK(cudaCreateTextureObject(&level.texture, &resource, &texture, nullptr));
      } else {
        buffers_.push_back(std::make_unique<DeviceBuffer>());
        buffers_.back()->upload(bytes.data(), bytes.size());
        level.pool = buffers_.back()->as<std::uint8_t>();
      }
    }
    builtFor_ = &layout;
  }

  void apply(codec::kernels::SvmmView& view) const {
    for (std::size_t L = 0; L < levels_.size(); ++L) {
      const Level& level = levels_[L];
      if (!level.texture && !level.pool) continue;
      view.level[L].pool = level.pool;
      view.level[L].texture = level.texture;
      view.level[L].poolULog2 = level.uLog2, view.level[L].poolVLog2 = level.vLog2;
    }
  }

 private:
  struct Level {
    cudaArray_t array = nullptr;
    cudaTextureObject_t texture = 0;
    const std::uint8_t* pool = nullptr;
    int uLog2 = 0, vLog2 = 0;
  };
  void release() {
    for (Level& level : levels_) {
      if (level.texture) cudaDestroyTextureObject(level.texture);
      if (level.array) cudaFreeArray(level.array);
    }
    levels_.clear();
    buffers_.clear();
    builtFor_ = nullptr;
  }
  const codec::svmm::Layout* builtFor_ = nullptr;
  std::vector<Level> levels_;
  std::vector<std::unique_ptr<DeviceBuffer>> buffers_;
};

template <class View>
__global__ void raycastKernel(View view, kernels::RayFrame frame, kernels::TransferLut lut,
                              kernels::SkipGrid skip, int tileX, int tileY, int tileW, int tileH,
                              std::uint32_t* out, unsigned long long* samples) {
  const int x = int(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = int(blockIdx.y * blockDim.y + threadIdx.y);
  unsigned count = 0;
  if (x < tileW && y < tileH) {
    const auto r = kernels::raycastPixel(view, frame, lut, skip, tileX + x, tileY + y);
    out[std::size_t(y) * std::size_t(tileW) + std::size_t(x)] = kernels::packRgba8(r.rgba);
    count = r.samples;
  }
  // One atomic per warp instead of one per pixel.
  count = __reduce_add_sync(0xffffffffu, count);
  if ((threadIdx.x + threadIdx.y * blockDim.x) % 32 == 0)
    atomicAdd(samples, (unsigned long long)count);
}

class CudaBackend final : public Backend {
 public:
  CudaBackend() {
    int device = 0;
    VOXWALL_CUDA_CHECK(cudaGetDevice(&device));
    cudaDeviceProp prop{};
    VOXWALL_CUDA_CHECK(cudaGetDeviceProperties(&prop, device));
    name_ = std::string("cuda (") + prop.name + ")";
    prop_ = prop;
    VOXWALL_CUDA_CHECK(cudaMalloc(&samples_, sizeof(unsigned long long)));
  }
  ~CudaBackend() override {
    if (samples_) cudaFree(samples_);
  }
  std::string name() const override { return name_; }

  TileStats renderTile(const RenderVolume& volume, const FramePlan& plan, const Rect& tile,
                       Image& out, CostGrid* costs) override {
    if (tile.width <= 0 || tile.height <= 0) throw std::invalid_argument("empty tile");
    const auto start = std::chrono::steady_clock::now();
    const auto payload = volume.payload();
    if (payload.data() != uploadedFrom_ || payload.size() != uploadedBytes_) {
      volumeBytes_.upload(payload.data(), payload.size());
      uploadedFrom_ = payload.data();
      uploadedBytes_ = payload.size();
    }
    lut_.upload(plan.lut.entries.data(), plan.lut.entries.size() * sizeof(glm::vec4));
    kernels::SkipGrid skip = plan.skip;
    if (skip.empty) {
      skipCells_.upload(plan.emptyCells.data(), plan.emptyCells.size());
      skip.empty = skipCells_.as<std::uint8_t>();
    }
    if (skip.fineEmpty) {
      fineSkipCells_.upload(plan.fineEmptyCells.data(), plan.fineEmptyCells.size());
      skip.fineEmpty = fineSkipCells_.as<std::uint8_t>();
    }
    const std::size_t pixels = std::size_t(tile.width) * std::size_t(tile.height);
    image_.reserve(pixels * sizeof(std::uint32_t));
    VOXWALL_CUDA_CHECK(cudaMemset(samples_, 0, sizeof(unsigned long long)));
    const dim3 block(16, 8);
    const dim3 grid((tile.width + 15) / 16, (tile.height + 7) / 8);
    const auto lut = plan.lut.view(lut_.as<glm::vec4>());
    std::visit(
        [&](const auto& hostView) {
          using View = std::decay_t<decltype(hostView)>;
          View view = std::get<View>(volume.view(volumeBytes_.as<std::byte>()));
          if constexpr (std::is_same_v<View, codec::kernels::SvmmView>) {
            svmmPools_.build(*volume.svmmLayout(), prop_);
            svmmPools_.apply(view);
          }
          raycastKernel<<<grid, block>>>(view, plan.ray, lut, skip, tile.x, tile.y, tile.width,
                                         tile.height, image_.as<std::uint32_t>(), samples_);
        },
        volume.view());
    VOXWALL_CUDA_CHECK(cudaGetLastError());
    out = Image(tile.width, tile.height);
    VOXWALL_CUDA_CHECK(cudaMemcpy(out.pixels.data(), image_.as<std::uint32_t>(),
                                  pixels * sizeof(std::uint32_t), cudaMemcpyDeviceToHost));
    unsigned long long samples = 0;
    VOXWALL_CUDA_CHECK(cudaMemcpy(&samples, samples_, sizeof samples, cudaMemcpyDeviceToHost));
    TileStats stats;
    stats.samples = samples;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // No per-block clock on the device: the tile's time is spread evenly over its cells.
    if (costs) costs->add(tile, stats.seconds);
    return stats;
  }

 private:
  std::string name_;
  cudaDeviceProp prop_{};
  SvmmPools svmmPools_;
  DeviceBuffer volumeBytes_, lut_, skipCells_, fineSkipCells_, image_;
  const std::byte* uploadedFrom_ = nullptr;
  std::size_t uploadedBytes_ = 0;
  unsigned long long* samples_ = nullptr;
};

}  // namespace

bool cudaAvailable(std::string* reason) {
  int count = 0;
  const cudaError_t error = cudaGetDeviceCount(&count);
  if (error != cudaSuccess) {
    if (reason) *reason = std::string("no usable CUDA device: ") + cudaGetErrorString(error);
    return false;
  }
  if (count == 0) {
    if (reason) *reason = "no CUDA device found";
    return false;
  }
  return true;
}

std::unique_ptr<Backend> makeCudaBackend() {
  std::string reason;
  if (!cudaAvailable(&reason)) throw CudaError(reason);
  return std::make_unique<CudaBackend>();
}

}  // namespace voxwall::node
