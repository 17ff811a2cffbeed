// Volume sources: a volume in memory, or a file read in slabs with pread().
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/errors.hpp>

#include "../file_util.hpp"

namespace voxwall::codec {

void VolumeSource::readSlices(int z0, int count, std::span<std::byte> out) const {
  if (z0 < 0 || z0 >= dims.z || count < 0 || out.size() < std::size_t(count) * sliceBytes())
    throw std::invalid_argument("readSlices: slices " + std::to_string(z0) + " + " +
                                std::to_string(count) + " outside the volume or the buffer");
  const int inside = std::min(count, dims.z - z0);
  read(z0, inside, out.data());
  for (int z = inside; z < count; ++z)
    std::memcpy(out.data() + std::size_t(z) * sliceBytes(),
                out.data() + std::size_t(inside - 1) * sliceBytes(), sliceBytes());
}

Volume VolumeSource::headerVolume() const {
  Volume v;
  v.dims = dims, v.spacing = spacing, v.type = type;
  v.orientation = orientation;
  v.valueMin = valueMin, v.valueMax = valueMax;
  return v;
}

std::pair<double, double> VolumeSource::dataRange() const {
  const Volume* v = inMemory();
  if (!v) return {valueMin, valueMax};
  return dispatchScalar(v->type, [&](auto t) -> std::pair<double, double> {
    auto s = v->as<decltype(t)>();
    if (s.empty()) return {0.0, 0.0};
    const auto [lo, hi] = std::minmax_element(s.begin(), s.end());
    return {double(*lo), double(*hi)};
  });
}

Volume VolumeSource::readAll() const {
  Volume v = Volume::allocate(dims, type, spacing);
  v.orientation = orientation;
  v.valueMin = valueMin, v.valueMax = valueMax;
  read(0, dims.z, v.data.data());
  return v;
}

namespace {

class MemorySource final : public VolumeSource {
 public:
  MemorySource(const Volume* volume, Volume owned) : owned_(std::move(owned)) {
    volume_ = volume ? volume : &owned_;
    dims = volume_->dims, spacing = volume_->spacing, type = volume_->type;
    orientation = volume_->orientation;
    valueMin = volume_->valueMin, valueMax = volume_->valueMax;
    if (type == ScalarType::Float32)
      for (const float f : volume_->as<float>()) finite = finite && std::isfinite(f);
  }
  bool streams() const override { return false; }
  const Volume* inMemory() const override { return volume_; }
  void setSpacing(glm::dvec3 s) override {
    if (volume_ != &owned_) throw std::logic_error("setSpacing on a borrowed volume");
    spacing = owned_.spacing = s;
  }
  void setOrientation(const Orientation& o) override {
    if (volume_ != &owned_) throw std::logic_error("setOrientation on a borrowed volume");
    orientation = owned_.orientation = o;
  }

 protected:
  void read(int z0, int count, std::byte* out) const override {
    std::memcpy(out, volume_->data.data() + std::size_t(z0) * sliceBytes(),
                std::size_t(count) * sliceBytes());
  }

 private:
  Volume owned_;
  const Volume* volume_;
};

// Voxels at `offset` of `file`, read with pread and byte-swapped when big endian.
class FileSource final : public VolumeSource {
 public:
  FileSource(const std::string& path, const SlabLayout& slab, Progress& progress)
      : path_(path),
        file_(slab.file),
        offset_(slab.layout.headerBytes),
        bigEndian_(slab.layout.bigEndian) {
    dims = slab.layout.dims, type = slab.layout.type, spacing = slab.layout.spacing;
    orientation = slab.layout.orientation;
    fd_ = ::open(file_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) throw FormatError(path_, std::strerror(errno));
    findRange(progress);
  }
  ~FileSource() override { ::close(fd_); }
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;
  bool streams() const override { return true; }
  const Volume* inMemory() const override { return nullptr; }

 protected:
  void read(int z0, int count, std::byte* out) const override {
    std::size_t left = std::size_t(count) * sliceBytes();
    std::uint64_t at = offset_ + std::uint64_t(z0) * sliceBytes();
    std::byte* p = out;
    while (left > 0) {
      const ssize_t n = ::pread(fd_, p, std::min<std::size_t>(left, 1 << 26), off_t(at));
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw FormatError(path_, std::string("read failed: ") + std::strerror(errno));
      if (n == 0) throw FormatError(path_, "truncated: the file ended while reading its voxels");
      p += n, left -= std::size_t(n), at += std::uint64_t(n);
    }
    const std::size_t width = scalarBytes(type);
    if (bigEndian_ && width > 1)
      for (std::byte* v = out; v < p; v += width) std::reverse(v, v + width);
  }

 private:
  // One pass over the file in slabs of about 16 MiB: the value range the header stores.
  void findRange(Progress& progress) {
    const int slab = int(
        std::clamp<std::size_t>((std::size_t(16) << 20) / sliceBytes(), 1, std::size_t(dims.z)));
    std::vector<std::byte> buffer(std::size_t(slab) * sliceBytes());
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    progress.begin("reading", std::uint64_t(dims.z));
    for (int z = 0; z < dims.z; z += slab) {
      const int n = std::min(slab, dims.z - z);
      read(z, n, buffer.data());
      dispatchScalar(type, [&](auto t) {
        using T = decltype(t);
        const T* v = reinterpret_cast<const T*>(buffer.data());
        const std::size_t count = std::size_t(n) * sliceVoxels();
        if constexpr (std::is_floating_point_v<T>)
          for (std::size_t i = 0; i < count; ++i) finite = finite && std::isfinite(v[i]);
        const auto [a, b] = std::minmax_element(v, v + count);
        lo = std::min(lo, double(*a)), hi = std::max(hi, double(*b));
      });
      progress.advance(std::uint64_t(n));
    }
    progress.end();
    valueMin = lo, valueMax = hi;
  }

  std::string path_, file_;
  std::uint64_t offset_;
  bool bigEndian_;
  int fd_ = -1;
};

}  // namespace

std::unique_ptr<VolumeSource> memorySource(const Volume& volume) {
  return std::make_unique<MemorySource>(&volume, Volume{});
}

std::unique_ptr<VolumeSource> memorySource(Volume&& volume) {
  return std::make_unique<MemorySource>(nullptr, std::move(volume));
}

std::unique_ptr<VolumeSource> openVolumeSource(const std::string& path, const ReadOptions& options,
                                               Progress& progress) {
  const std::optional<RawLayout>& raw = options.raw;
  std::optional<SlabLayout> slab;
  std::error_code ec;
  const bool regular = std::filesystem::is_regular_file(path, ec);
  if (raw && raw->dims.x > 0) {
    // A gzipped raw file is read whole (readRaw refuses it in its own words).
    if (regular && extensionOf(path) != "raw.gz") {
      checkRawFile(path, *raw);
      slab = SlabLayout{path, *raw};
    }
  } else if (regular) {
    const VolumeFormat format = volumeFormatOf(path);
    if (format == VolumeFormat::Nrrd) slab = nrrdSlabLayout(path);
    if (format == VolumeFormat::Nifti) slab = niftiSlabLayout(path);
  }
  if (slab) return slabSource(path, *slab, progress);
  return memorySource(readVolume(path, options));
}

std::unique_ptr<VolumeSource> slabSource(const std::string& path, const SlabLayout& slab,
                                         Progress& progress) {
  try {
    return std::make_unique<FileSource>(path, slab, progress);
  } catch (const std::bad_alloc&) {
    throw FormatError(path, "not enough memory to read it");
  }
}

}  // namespace voxwall::codec
