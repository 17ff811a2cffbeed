#include <xxhash.h>

#include <algorithm>
#include <atomic>
#include <glm/geometric.hpp>
#include <mutex>
#include <type_traits>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/host_tables.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/progress.hpp>
#include <voxwall/node/render_volume.hpp>

namespace voxwall::node {
namespace {
std::uint64_t nextPayloadId() {
  static std::atomic<std::uint64_t> payloads{0};
  return ++payloads;
}

// What a step's value ranges are of, for the ranks on a host that make them together
// (hosttables::RangeShare): the codec, the step's description, the render flags and every
// section's bytes. 0 where there is no shared file (nothing is hashed then).
std::uint64_t rangeKey(const codec::Codec& c, const codec::VolumeInfo& own, int step,
                       const codec::CodecOptionValues& renderOptions,
                       const codec::SectionSet& sections) {
  if (!codec::hosttables::active() || !c.compresses()) return 0;
  XXH64_state_t* state = XXH64_createState();
  if (!state) return 0;  // no memory for the hash's state: the ranges are made alone
  XXH64_reset(state, 0x72616e676573ull);
  const auto add = [&](const void* p, std::size_t n) { XXH64_update(state, p, n); };
  const std::string name(c.name());
  add(name.data(), name.size() + 1);
  const std::int64_t head[] = {own.dims.x, own.dims.y, own.dims.z, std::int64_t(own.type), step};
  add(head, sizeof head);
  const double range[] = {own.valueMin, own.valueMax};
  add(range, sizeof range);
  for (const std::string& flag : renderOptions.flags()) {
    const std::string value = renderOptions.text(flag, "");
    add(flag.data(), flag.size() + 1), add(value.data(), value.size() + 1);
  }
  for (const auto& [id, bytes] : sections.sections) {
    const std::uint64_t head2[] = {id, bytes.size()};
    add(head2, sizeof head2), add(bytes.data(), bytes.size());
  }
  const std::uint64_t key = XXH64_digest(state);
  XXH64_freeState(state);
  return key ? key : 1;
}
}  // namespace

RenderVolume RenderVolume::open(const std::string& path, const codec::ReadOptions& options,
                                const codec::CodecOptionValues& renderOptions) {
  if (!options.isRaw() && codec::isContainerFile(path))
    return fromContainer(codec::ContainerFile::open(path), renderOptions);
  refuseRenderOptions(renderOptions, path);
  RenderVolume v = fromVolume(codec::readVolume(path, options));
  v.source_ = path;
  return v;
}

void RenderVolume::refuseRenderOptions(const codec::CodecOptionValues& renderOptions,
                                       const std::string& path) {
  if (!renderOptions.flags().empty())
    throw std::invalid_argument(renderOptions.flags().front() + " needs a .vwz file; " + path +
                                " is rendered from raw bricks (no codec)");
}

RenderVolume RenderVolume::fromContainer(codec::ContainerFile file,
                                         const codec::CodecOptionValues& renderOptions) {
  RenderVolume v;
  v.file_ = std::make_shared<codec::ContainerFile>(std::move(file));
  v.sections_ = v.file_->sections();
  v.info_ = v.file_->info();
  v.storedBytes_ = v.file_->fileBytes();
  v.source_ = v.file_->path();
  v.renderOptions_ = renderOptions;
  v.init(renderOptions);
  return v;
}

std::pair<double, double> RenderVolume::stepRange(int k) const {
  if (k < 0 || k >= steps()) throw std::invalid_argument("no step " + std::to_string(k));
  const codec::VolumeInfo own = file_ ? file_->stepInfo(k) : info_;
  return {own.valueMin, own.valueMax};
}

RenderVolume RenderVolume::atStep(int step) const {
  if (step < 0 || step >= steps())
    throw std::invalid_argument(source_ + ": no step " + std::to_string(step) + " (it holds " +
                                std::to_string(steps()) + ")");
  if (step == step_) return *this;
  RenderVolume v;
  v.file_ = file_;
  v.sections_ = file_->stepSections(step);
  v.info_ = info_;
  v.storedBytes_ = storedBytes_;
  v.source_ = source_;
  v.renderOptions_ = renderOptions_;
  v.step_ = step;
  v.init(renderOptions_);
  return v;
}

RenderVolume RenderVolume::fromVolume(const codec::Volume& volume, int brickVoxels) {
  voxwall::Progress quiet;
  return fromCompressed(codec::rawbricks::encode(volume, {brickVoxels}, quiet));
}

RenderVolume RenderVolume::fromCompressed(codec::CompressedVolume volume) {
  RenderVolume v;
  v.memory_ = std::make_shared<codec::CompressedVolume>(std::move(volume));
  v.sections_ = v.memory_->view();
  v.info_ = v.memory_->info;
  v.storedBytes_ = v.memory_->payloadBytes();
  v.source_ = "<memory>";
  v.init();
  return v;
}

void RenderVolume::init(const codec::CodecOptionValues& renderOptions) {
  const codec::Codec& c = codec::codecOf(info_, sections_.source);
  for (const std::string& flag : renderOptions.flags()) {
    bool owned = false;
    for (const codec::CodecOption& o : c.renderOptions()) owned = owned || o.flag == flag;
    if (owned) continue;
    throw std::invalid_argument(flag + " needs a file of codec " +
                                codec::codecsTaking(flag, &codec::Codec::renderOptions) + "; " +
                                source_ + " is " + std::string(c.name()));
  }
  // The codec sees the step as a volume of its own (its own value range).
  const codec::VolumeInfo own = file_ ? file_->stepInfo(step_) : info_;
  payload_ = c.openWith(own, sections_, renderOptions);
  payloadId_ = nextPayloadId();
  {
    // The ranks on this host that open the same step now make its ranges together.
    const codec::hosttables::RangeShare share(rangeKey(c, own, step_, renderOptions, sections_));
    ranges_ = payload_->rangeGrid();
  }
  ranges_.pack();  // read again only when a transfer function changes
  // Raw bricks are what a decoded volume would be: only a codec that compresses gets one.
  if (c.compresses() && info_.steps == 1 && renderOptions.flags().empty())
    decoded_ = std::make_shared<Decoded>();
}

struct RenderVolume::Decoded {
  std::once_flag once;
  std::optional<codec::rawbricks::DecodedBricks> bricks;
  std::unique_ptr<codec::RenderPayload> payload;
  std::uint64_t id = 0;
};

const codec::RenderPayload* RenderVolume::decodedPayload() const {
  if (!decoded_) return nullptr;
  std::call_once(decoded_->once, [this] {
    const codec::Codec& c = codec::codecOf(info_, sections_.source);
    const codec::VolumeInfo own = file_ ? file_->stepInfo(step_) : info_;
    decoded_->bricks.emplace(c.decode(own, sections_), sections_.source);
    decoded_->payload = decoded_->bricks->payload();
    decoded_->id = nextPayloadId();
  });
  return decoded_->payload.get();
}

std::uint64_t RenderVolume::decodedPayloadId() const { return decodedPayload() ? decoded_->id : 0; }

std::uint64_t RenderVolume::decodedBytes() const {
  return decoded_ ? codec::rawbricks::DecodedBricks::bytesFor(info_.dims, info_.type) : 0;
}

bool RenderVolume::traversal() const {
  return std::visit(
      [](const auto& v) {
        return requires { std::decay_t<decltype(v)>::kTraversal; };
      },
      view());
}

std::uint64_t RenderVolume::fingerprint() const {
  XXH64_state_t* state = XXH64_createState();
  XXH64_reset(state, 0);
  auto add = [&](const auto& value) { XXH64_update(state, &value, sizeof value); };
  add(info_.codec), add(info_.type), add(info_.dims.x), add(info_.dims.y), add(info_.dims.z);
  add(info_.spacing.x), add(info_.spacing.y), add(info_.spacing.z);
  add(info_.valueMin), add(info_.valueMax);
  add(info_.orientation.direction), add(info_.orientation.origin);
  if (steps() > 1) add(info_.steps);  // (a single volume's fingerprint is what it always was)
  for (int k = 0; k < steps(); ++k)
    for (const auto& [id, bytes] : (file_ ? file_->stepSections(k) : sections_).sections) {
      if (steps() > 1) add(k);
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
