#include <xxhash.h>

#include <glm/geometric.hpp>
#include <voxwall/codec/errors.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/node/render_volume.hpp>

namespace voxwall::node {

RenderVolume RenderVolume::open(const std::string& path,
                                const std::optional<codec::RawLayout>& raw) {
  if ((!raw || raw->dims.x <= 0) && codec::isContainerFile(path))
    return fromContainer(codec::ContainerFile::open(path));
  RenderVolume v = fromVolume(codec::readVolume(path, raw));
  v.source_ = path;
  return v;
}

RenderVolume RenderVolume::fromContainer(codec::ContainerFile file) {
  RenderVolume v;
  v.file_ = std::make_shared<codec::ContainerFile>(std::move(file));
  v.sections_ = v.file_->sections();
  v.info_ = v.file_->info();
  v.storedBytes_ = v.file_->fileBytes();
  v.source_ = v.file_->path();
  v.init();
  return v;
}

RenderVolume RenderVolume::fromVolume(const codec::Volume& volume, int brickVoxels) {
  codec::Progress quiet;
  RenderVolume v;
  v.memory_ =
      std::make_shared<codec::CompressedVolume>(codec::raw::encode(volume, {brickVoxels}, quiet));
  v.sections_ = v.memory_->view();
  v.info_ = v.memory_->info;
  v.storedBytes_ = v.memory_->payloadBytes();
  v.source_ = "<memory>";
  v.init();
  return v;
}

void RenderVolume::init() {
  switch (info_.codec) {
    case codec::CodecId::Raw:
      rawLayout_.emplace(info_, sections_);
      ranges_ = rawLayout_->rangeGrid();
      return;
    case codec::CodecId::Vq:
      vqLayout_.emplace(info_, sections_);
      ranges_ = vqLayout_->rangeGrid();
      return;
    case codec::CodecId::Svmm:
      svmmLayout_.emplace(info_, sections_);
      if (svmmLayout_->format() == codec::kernels::kSvmmRgba32)
        throw FormatError(sections_.source,
                          "an RGBA svmm volume cannot be rendered: the raycaster maps scalar "
                          "values through a transfer function");
      ranges_ = svmmLayout_->rangeGrid();
      return;
    default:
      throw FormatError(sections_.source, "codec '" + std::string(codec::codecName(info_.codec)) +
                                              "' cannot be rendered by this build");
  }
}

std::span<const std::byte> RenderVolume::payload() const {
  if (vqLayout_) return vqLayout_->dataBytes();
  if (svmmLayout_) return svmmLayout_->dataBytes();
  return rawLayout_->brickBytes();
}

ViewVariant RenderVolume::view(const std::byte* base) const {
  if (vqLayout_) return vqLayout_->view(base);
  if (svmmLayout_) return svmmLayout_->view(base);
  return codec::dispatchScalar(
      info_.type, [&](auto t) -> ViewVariant { return rawLayout_->view<decltype(t)>(base); });
}

std::uint64_t RenderVolume::fingerprint() const {
  XXH64_state_t* state = XXH64_createState();
  XXH64_reset(state, 0);
  auto add = [&](const auto& value) { XXH64_update(state, &value, sizeof value); };
  add(info_.codec), add(info_.type), add(info_.dims.x), add(info_.dims.y), add(info_.dims.z);
  add(info_.spacing.x), add(info_.spacing.y), add(info_.spacing.z);
  add(info_.valueMin), add(info_.valueMax);
  for (const auto& [id, bytes] : sections_.sections) {
    add(id);
    const std::uint64_t size = bytes.size();
    add(size);
    XXH64_update(state, bytes.data(), bytes.size());
  }
  const std::uint64_t hash = XXH64_digest(state);
  XXH64_freeState(state);
  return hash;
}

double boundingRadius(const codec::VolumeInfo& info) {
  return 0.5 * glm::length(glm::dvec3(info.dims) * info.spacing);
}

}  // namespace voxwall::node
