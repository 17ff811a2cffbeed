// A volume read a slab of z-slices at a time, so an encoder holds a bounded window of it rather
// than the whole input. Raw files, NRRD files with raw encoding and uncompressed NIfTI files whose
// voxels are stored in one of voxwall's scalar types are read from the file with pread(); every
// other input (gzip, slice stacks, types that are converted) is read whole into memory first.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec {

class VolumeSource {
 public:
  virtual ~VolumeSource() = default;

  glm::ivec3 dims{0, 0, 0};
  glm::dvec3 spacing{1, 1, 1};  // change it with setSpacing()
  Orientation orientation{};    // change it with setOrientation()
  ScalarType type = ScalarType::UInt8;
  double valueMin = 0, valueMax = 0;  // of every voxel (a first pass over a file finds them)
  bool finite = true;                 // false when float data holds NaN or infinities

  std::size_t sliceVoxels() const { return std::size_t(dims.x) * std::size_t(dims.y); }
  std::size_t sliceBytes() const { return sliceVoxels() * scalarBytes(type); }
  std::size_t voxelCount() const { return sliceVoxels() * std::size_t(dims.z); }

  // Copies slices z0 .. z0+count-1 into `out` (count * sliceBytes() bytes), in the volume's type,
  // native endian. Slices past the last one repeat the last one (an encoder's bricks and aprons
  // clamp at the volume's edge); z0 must lie in the volume. Throws FormatError on a read error.
  void readSlices(int z0, int count, std::span<std::byte> out) const;
  // Whether readSlices() reads the file (true) or copies from a volume held in memory.
  virtual bool streams() const = 0;
  // The whole volume in memory (what an encoder that does not stream works on).
  Volume readAll() const;
  // The volume this source copies from, when it holds one (no copy needed); null when it streams.
  virtual const Volume* inMemory() const = 0;
  // The range of the voxels themselves: scanned for a volume in memory (whose header need not
  // say), what the first pass over a file found for a file.
  std::pair<double, double> dataRange() const;
  // Overrides the file's spacing (`compress --spacing`), also in the volume inMemory() gives
  // when the source owns it; throws std::logic_error for a source that borrows its volume.
  virtual void setSpacing(glm::dvec3 s) { spacing = s; }
  // Overrides the file's orientation (`compress --orientation`), the same way.
  virtual void setOrientation(const Orientation& o) { orientation = o; }
  // The header of a volume with this source's dims, type, spacing, orientation and range, and
  // no data.
  Volume headerVolume() const;

 protected:
  // Slices z0 .. z0+count-1, all inside the volume.
  virtual void read(int z0, int count, std::byte* out) const = 0;
};

// Slices of a source held for random access, loaded a window at a time: load() reads slices z0 ..
// z0+count-1 (the last slice repeated past the volume's end) unless they are held already, and
// at() reads a voxel of them.
template <class T>
class SliceWindow {
 public:
  explicit SliceWindow(const VolumeSource& source) : source_(source) {}
  void load(int z0, int count) {
    if (z0 == z0_ && count <= count_) return;
    buffer_.resize(std::size_t(count) * source_.sliceVoxels());
    source_.readSlices(z0, count, std::as_writable_bytes(std::span(buffer_)));
    z0_ = z0, count_ = count;
  }
  T at(int x, int y, int z) const {
    return buffer_[(std::size_t(z - z0_) * std::size_t(source_.dims.y) + std::size_t(y)) *
                       std::size_t(source_.dims.x) +
                   std::size_t(x)];
  }

 private:
  const VolumeSource& source_;
  std::vector<T> buffer_;
  int z0_ = -1, count_ = 0;
};

// A source that copies from `volume`, which must outlive it (or owns it when moved in).
std::unique_ptr<VolumeSource> memorySource(const Volume& volume);
std::unique_ptr<VolumeSource> memorySource(Volume&& volume);

// Where a file's voxels lie, when they lie uncompressed in one of voxwall's types.
struct SlabLayout {
  std::string file;  // the file holding the voxels (a detached NRRD's data file)
  RawLayout layout;  // dims, type, spacing, endianness, and the offset of the first voxel
};
// For a NRRD file with raw encoding and one data file, and an uncompressed single-file or
// .hdr/.img NIfTI file without scaling; nullopt for any other file of those formats (which
// readVolume reads whole). Throws FormatError for files readVolume refuses too.
// `step` >= 0: that volume of a NRRD or NIfTI series (nrrdStepCount, niftiStepCount); -1: the
// file must hold one volume.
std::optional<SlabLayout> nrrdSlabLayout(const std::string& path, int step = -1);
std::optional<SlabLayout> niftiSlabLayout(const std::string& path, int step = -1);

// The voxels `slab` describes, read from the file in slabs (the first pass finds their range,
// reporting on `progress`); `path` names the input in errors.
std::unique_ptr<VolumeSource> slabSource(const std::string& path, const SlabLayout& slab,
                                         Progress& progress);

// The source for `path`: read in slabs where the format allows (raw with `options.raw` given,
// NRRD and NIfTI as above), else read whole with readVolume() (DICOM among them). Opening a file
// source reads the file once to find its value range, reporting on `progress`. Throws
// FormatError like readVolume().
std::unique_ptr<VolumeSource> openVolumeSource(const std::string& path, const ReadOptions& options,
                                               Progress& progress);

}  // namespace voxwall::codec
