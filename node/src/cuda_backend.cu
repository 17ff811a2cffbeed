// The CUDA backend: uploads the volume once (decoded whole as raw bricks where they fit, else the
// compressed bytes: DeviceDecode), the transfer-function table and the skip grid per frame, and
// launches one thread per pixel running the same raycastPixel as the CPU backend. Only allocation,
// upload, launch and download live here (docs/architecture.md); the kernel is compiled per view
// type (cuda_launch.hpp).
#include <cuda_runtime.h>

#include <chrono>
#include <memory>
#include <span>
#include <string>
#include <type_traits>
#include <vector>
#include <voxwall/node/renderer.hpp>

#include "cuda_launch.hpp"

// node/CMakeLists.txt compiles one unit per view type (cuda_view.cu.in), as for the CPU.

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
  std::size_t capacity() const { return capacity_; }

 private:
  void* ptr_ = nullptr;
  std::size_t capacity_ = 0;
};

// The 3D arrays a payload asks for (render_payload.hpp): each a texture object over a CUDA
// array, or, when larger than the device's 3D texture limits, linear device memory in the same
// layout. Built once per payload.
class DeviceArrays {
 public:
  DeviceArrays() = default;
  DeviceArrays(const DeviceArrays&) = delete;
  DeviceArrays& operator=(const DeviceArrays&) = delete;
  ~DeviceArrays() { release(); }

  // `id`: the payload's RenderVolume::payloadId.
  std::span<const codec::DeviceArray> build(const codec::RenderPayload& payload, std::uint64_t id,
                                            const cudaDeviceProp& prop) {
    if (id == builtFor_) return handles_;
    release();
    for (const codec::DeviceArraySpec& spec : payload.deviceArrays()) {
      codec::DeviceArray handle;
      if (spec.width <= std::size_t(prop.maxTexture3D[0]) &&
          spec.height <= std::size_t(prop.maxTexture3D[1]) &&
          spec.depth <= std::size_t(prop.maxTexture3D[2])) {
        handle.texture = makeTexture(spec);
      } else {
        buffers_.push_back(std::make_unique<DeviceBuffer>());
        buffers_.back()->upload(spec.bytes.data(), spec.bytes.size());
        handle.linear = buffers_.back()->as<std::uint8_t>();
      }
      handles_.push_back(handle);
    }
    builtFor_ = id;
    return handles_;
  }

 private:
  cudaTextureObject_t makeTexture(const codec::DeviceArraySpec& spec) {
    const std::size_t eb = std::size_t(spec.elementBytes);
    const cudaChannelFormatDesc desc = eb == 1   ? cudaCreateChannelDesc<unsigned char>()
                                       : eb == 2 ? cudaCreateChannelDesc<unsigned short>()
                                                 : cudaCreateChannelDesc<unsigned int>();
    const cudaExtent extent = make_cudaExtent(spec.width, spec.height, spec.depth);
    cudaArray_t array = nullptr;
    VOXWALL_CUDA_CHECK(cudaMalloc3DArray(&array, &desc, extent));
    arrays_.push_back(array);
    cudaMemcpy3DParms copy{};
    copy.srcPtr = make_cudaPitchedPtr(const_cast<std::uint8_t*>(spec.bytes.data()), spec.width * eb,
                                      spec.width, spec.height);
    copy.dstArray = array;
    copy.extent = extent;
    copy.kind = cudaMemcpyHostToDevice;
    VOXWALL_CUDA_CHECK(cudaMemcpy3D(&copy));
    cudaResourceDesc resource{};
    resource.resType = cudaResourceTypeArray;
    resource.res.array.array = array;
    cudaTextureDesc texture{};
    for (int a = 0; a < 3; ++a) texture.addressMode[a] = cudaAddressModeClamp;
    texture.filterMode = cudaFilterModePoint;
    texture.readMode = cudaReadModeElementType;
    texture.normalizedCoords = 0;
    cudaTextureObject_t object = 0;
    VOXWALL_CUDA_CHECK(cudaCreateTextureObject(&object, &resource, &texture, nullptr));
    textures_.push_back(object);
    return object;
  }
  void release() {
    for (cudaTextureObject_t t : textures_) cudaDestroyTextureObject(t);
    for (cudaArray_t a : arrays_) cudaFreeArray(a);
    textures_.clear(), arrays_.clear(), buffers_.clear(), handles_.clear();
    builtFor_ = 0;
  }
  std::uint64_t builtFor_ = 0;  // RenderVolume::payloadId
  std::vector<codec::DeviceArray> handles_;
  std::vector<cudaTextureObject_t> textures_;
  std::vector<cudaArray_t> arrays_;
  std::vector<std::unique_ptr<DeviceBuffer>> buffers_;
};

class CudaBackend final : public Backend {
 public:
  explicit CudaBackend(DeviceDecode decode) : decode_(decode) {
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

  // A kernel runs to its end: `stop` is checked before it is launched.
  TileStats renderTile(const RenderVolume& volume, const FramePlan& plan, const Rect& tile,
                       Image& out, CostGrid* costs, const std::atomic<bool>* stop) override {
    if (tile.width <= 0 || tile.height <= 0) throw std::invalid_argument("empty tile");
    if (stop && stop->load()) {
      out = Image(tile.width, tile.height);
      TileStats stopped;
      stopped.stopped = true;
      return stopped;
    }
    const auto start = std::chrono::steady_clock::now();
    // Mip levels (nearest sampling, level of detail) are the compressed view's alone.
    const bool whole = !plan.ray.nearest && plan.ray.lodAngle <= 0.0f && decodesWhole(volume);
    const codec::RenderPayload& payload = whole ? *volume.decodedPayload() : volume.payload();
    const std::uint64_t payloadId = whole ? volume.decodedPayloadId() : volume.payloadId();
    if (payloadId != uploadedFor_) {  // another volume, or another step of it
      const auto bytes = payload.bytes();
      volumeBytes_.upload(bytes.data(), bytes.size());
      uploadedFor_ = payloadId;
    }
    const std::vector<glm::vec4> table = plan.lut.packed();
    lut_.upload(table.data(), table.size() * sizeof(glm::vec4));
    kernels::SkipGrid skip = plan.skip;
    if (skip.empty) {
      skipCells_.upload(plan.emptyCells->data(), plan.emptyCells->size());
      skip.empty = skipCells_.as<std::uint8_t>();
    }
    if (skip.fineEmpty) {
      fineSkipCells_.upload(plan.fineEmptyBits->data(),
                            plan.fineEmptyBits->size() * sizeof(std::uint32_t));
      skip.fineEmpty = fineSkipCells_.as<std::uint32_t>();
    }
    const std::size_t pixels = std::size_t(tile.width) * std::size_t(tile.height);
    image_.reserve(pixels * sizeof(std::uint32_t));
    VOXWALL_CUDA_CHECK(cudaMemset(samples_, 0, sizeof(unsigned long long)));
    const dim3 block(16, 8);
    const dim3 grid((tile.width + 15) / 16, (tile.height + 7) / 8);
    const auto lut = plan.lut.view(lut_.as<glm::vec4>());
    const auto arrays = deviceArrays_.build(payload, payloadId, prop_);
    cuda::Launch launch;
    launch.grid = grid, launch.block = block;
    launch.frame = plan.ray, launch.lut = lut, launch.skip = skip;
    launch.tileX = tile.x, launch.tileY = tile.y, launch.tileW = tile.width;
    launch.tileH = tile.height;
    launch.out = image_.as<std::uint32_t>(), launch.samples = samples_;
    std::visit([&](const auto& view) { cuda::launchRaycast(view, launch); },
               payload.deviceView(volumeBytes_.as<std::byte>(), arrays));
    VOXWALL_CUDA_CHECK(cudaGetLastError());
    out = Image(tile.width, tile.height);
    VOXWALL_CUDA_CHECK(cudaMemcpy(out.pixels.data(), image_.as<std::uint32_t>(),
                                  pixels * sizeof(std::uint32_t), cudaMemcpyDeviceToHost));
    unsigned long long samples = 0;
    VOXWALL_CUDA_CHECK(cudaMemcpy(&samples, samples_, sizeof samples, cudaMemcpyDeviceToHost));
    TileStats stats;
    stats.samples = samples;
    stats.rays = std::uint64_t(tile.area());
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // No per-block clock on the device: the tile's time is spread evenly over its cells.
    if (costs) costs->add(tile, stats.seconds);
    return stats;
  }

 private:
  // Whether `volume` is sampled decoded whole: asked for, possible, and its bricks fit in what the
  // device has free (beside what this backend holds, which an upload replaces), with an eighth
  // of the device to spare. Decided once per volume.
  bool decodesWhole(const RenderVolume& volume) {
    if (volume.payloadId() == decidedFor_) return whole_;
    decidedFor_ = volume.payloadId();
    whole_ = false;
    if (decode_ != DeviceDecode::Whole || volume.decodedBytes() == 0) return false;
    std::size_t free = 0, total = 0;
    VOXWALL_CUDA_CHECK(cudaMemGetInfo(&free, &total));
    whole_ = volume.decodedBytes() + total / 8 <= free + volumeBytes_.capacity();
    return whole_;
  }

  std::string name_;
  DeviceDecode decode_;
  std::uint64_t decidedFor_ = 0;  // RenderVolume::payloadId of the last decodesWhole() decision
  bool whole_ = false;
  cudaDeviceProp prop_{};
  DeviceArrays deviceArrays_;
  DeviceBuffer volumeBytes_, lut_, skipCells_, fineSkipCells_, image_;
  std::uint64_t uploadedFor_ = 0;  // RenderVolume::payloadId of the bytes on the device
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

std::unique_ptr<Backend> makeCudaBackend(DeviceDecode decode) {
  std::string reason;
  if (!cudaAvailable(&reason)) throw CudaError(reason);
  return std::make_unique<CudaBackend>(decode);
}

}  // namespace voxwall::node
