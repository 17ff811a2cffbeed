// Volume sources: a file read in slabs gives the voxels readVolume gives, and an encoder that
// streams writes the same bytes from a file source as from the volume in memory.
#include <gtest/gtest.h>

#include <cstring>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/codec/registry.hpp>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/errors.hpp>

#include "support/patterned_volume.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::codec;
using voxwall::test::TempDir;

namespace {

Volume patternedVolume(ScalarType type) { return voxwall::test::patterned(type, {13, 7, 11}); }

std::string bytesOf(const Volume& v, bool bigEndian) {
  std::string s(reinterpret_cast<const char*>(v.data.data()), v.data.size());
  const std::size_t w = scalarBytes(v.type);
  if (bigEndian && w > 1)
    for (std::size_t i = 0; i < s.size(); i += w)
      std::reverse(s.begin() + long(i), s.begin() + long(i + w));
  return s;
}

// Reads the source in slabs of `slab` slices and expects the volume's voxels, range and header.
void expectReads(const VolumeSource& source, const Volume& want, int slab) {
  ASSERT_EQ(source.dims, want.dims);
  ASSERT_EQ(source.type, want.type);
  EXPECT_EQ(source.spacing, want.spacing);
  EXPECT_EQ(source.valueMin, want.valueMin);
  EXPECT_EQ(source.valueMax, want.valueMax);
  std::vector<std::byte> got(want.data.size());
  std::vector<std::byte> buffer(std::size_t(slab) * source.sliceBytes());
  for (int z = 0; z < want.dims.z; z += slab) {
    source.readSlices(z, slab, buffer);
    const int n = std::min(slab, want.dims.z - z);
    std::memcpy(got.data() + std::size_t(z) * source.sliceBytes(), buffer.data(),
                std::size_t(n) * source.sliceBytes());
    // Slices past the end repeat the last one.
    for (int extra = n; extra < slab; ++extra)
      EXPECT_EQ(std::memcmp(buffer.data() + std::size_t(extra) * source.sliceBytes(),
                            want.data.data() + std::size_t(want.dims.z - 1) * source.sliceBytes(),
                            source.sliceBytes()),
                0);
  }
  EXPECT_EQ(got, want.data);
}

}  // namespace

TEST(VolumeSource, ARawFileIsReadInSlabsWithItsHeaderAndByteOrder) {
  TempDir dir;
  for (const ScalarType type :
       {ScalarType::UInt8, ScalarType::UInt16, ScalarType::Int16, ScalarType::Float32})
    for (const bool big : {false, true}) {
      const Volume v = patternedVolume(type);
      const std::string path = dir.path("v.raw");
      test::writeFile(path, std::string(17, 'h') + bytesOf(v, big));
      RawLayout layout{v.dims, type, v.spacing, big, 17};
      Progress quiet;
      const auto source = openVolumeSource(path, layout, quiet);
      EXPECT_TRUE(source->streams());
      expectReads(*source, v, 3);
      expectReads(*source, readRaw(path, layout), 4);
    }
}

TEST(VolumeSource, AWrongRawSizeIsRefusedBeforeReading) {
  TempDir dir;
  const std::string path = dir.path("v.raw");
  test::writeFile(path, std::string(100, 'x'));
  Progress quiet;
  for (const glm::ivec3 dims : {glm::ivec3{5, 5, 5}, glm::ivec3{3, 3, 3}}) {
    try {
      openVolumeSource(path, RawLayout{dims, ScalarType::UInt8}, quiet);
      ADD_FAILURE() << "no error";
    } catch (const FormatError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
    }
  }
}

TEST(VolumeSource, AnUncompressedNiftiIsReadInSlabsAndAGzippedOneWhole) {
  TempDir dir;
  Progress quiet;
  for (const ScalarType type : {ScalarType::UInt8, ScalarType::Int16, ScalarType::Float32}) {
    const Volume v = patternedVolume(type);
    writeVolume(v, dir.path("v.nii"));
    const auto layout = niftiSlabLayout(dir.path("v.nii"));
    ASSERT_TRUE(layout.has_value());
    EXPECT_EQ(layout->layout.dims, v.dims);
    const auto source = openVolumeSource(dir.path("v.nii"), std::nullopt, quiet);
    EXPECT_TRUE(source->streams());
    expectReads(*source, readVolume(dir.path("v.nii")), 5);

    // Cut short, it is refused before any voxel is read.
    const std::string bytes = test::readFile(dir.path("v.nii"));
    test::writeFile(dir.path("cut.nii"), bytes.substr(0, bytes.size() - 7));
    try {
      openVolumeSource(dir.path("cut.nii"), std::nullopt, quiet);
      ADD_FAILURE() << "no error for a cut NIfTI file";
    } catch (const FormatError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(dir.path("cut.nii") + ": truncated", 0), 0u)
          << e.what();
    }

    writeVolume(v, dir.path("v.nii.gz"));
    EXPECT_FALSE(niftiSlabLayout(dir.path("v.nii.gz")).has_value());
    const auto whole = openVolumeSource(dir.path("v.nii.gz"), std::nullopt, quiet);
    EXPECT_FALSE(whole->streams());
    expectReads(*whole, readVolume(dir.path("v.nii.gz")), 5);
  }
}

TEST(VolumeSource, ARawEncodedNrrdIsReadInSlabsAttachedOrDetached) {
  TempDir dir;
  Progress quiet;
  const Volume v = patternedVolume(ScalarType::UInt16);
  const std::string header =
      "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 13 7 11\n"
      "spacings: 0.5 0.75 1.25\nendian: big\nencoding: raw\n";
  test::writeFile(dir.path("a.nrrd"), header + "\n" + bytesOf(v, true));
  test::writeFile(dir.path("d.nhdr"), header + "data file: d.bin\nbyte skip: 5\n");
  test::writeFile(dir.path("d.bin"), "12345" + bytesOf(v, true));
  test::writeFile(dir.path("t.nhdr"), header + "data file: t.bin\nbyte skip: -1\n");
  test::writeFile(dir.path("t.bin"), "junk" + bytesOf(v, true));
  for (const char* name : {"a.nrrd", "d.nhdr", "t.nhdr"}) {
    SCOPED_TRACE(name);
    ASSERT_TRUE(nrrdSlabLayout(dir.path(name)).has_value());
    const auto source = openVolumeSource(dir.path(name), std::nullopt, quiet);
    EXPECT_TRUE(source->streams());
    expectReads(*source, v, 4);
    expectReads(*source, readVolume(dir.path(name)), 4);
  }
  // gzip encoding (what writeVolume writes) is read whole.
  writeVolume(v, dir.path("g.nrrd"));
  EXPECT_FALSE(nrrdSlabLayout(dir.path("g.nrrd")).has_value());
  // A raw NRRD cut short is refused before any voxel is read.
  const std::string full = header + "\n" + bytesOf(v, true);
  test::writeFile(dir.path("cut.nrrd"), full.substr(0, full.size() - 10));
  EXPECT_THROW(openVolumeSource(dir.path("cut.nrrd"), std::nullopt, quiet), FormatError);
}

// Every codec writes the same file from a file read in slabs as from the volume in memory: the
// ones that stream by construction of the same code path over a different source, the others
// by reading the file whole.
TEST(VolumeSource, EveryCodecWritesTheSameFileFromASlabSourceAsFromMemory) {
  TempDir dir;
  const Volume v = generateSheppLogan(37, ScalarType::Int16);
  writeVolume(v, dir.path("v.nii"));
  Progress quiet;
  const auto source = openVolumeSource(dir.path("v.nii"), std::nullopt, quiet);
  ASSERT_TRUE(source->streams());
  for (const Codec* c : codecs()) {
    SCOPED_TRACE(std::string(c->name()));
    CodecOptionValues options;
    const auto example = c->exampleOptions();
    for (std::size_t i = 0; i < example.size(); ++i) {
      const bool value = i + 1 < example.size() && example[i + 1].rfind("--", 0) != 0;
      options.set(example[i], value ? example[i + 1] : "1");
      if (value) ++i;
    }
    std::string report1, report2;
    const auto fromMemory = serializeContainer(c->encode(v, options, quiet, report1));
    const auto fromFile = serializeContainer(c->encodeSource(*source, options, quiet, report2));
    EXPECT_EQ(fromMemory, fromFile);
  }
}
