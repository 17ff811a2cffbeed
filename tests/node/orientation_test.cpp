// The same scan stored in different orientations, read from NIfTI (RAS and LAS storage), NRRD
// (axes permuted) and DICOM, renders the same picture: the renderer places the grid in patient
// space through its orientation. And an anterior view shows the patient's left on the right.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <voxwall/codec/volume_io.hpp>
#include <voxwall/node/renderer.hpp>

#include "support/dicom_writer.hpp"
#include "support/image_expect.hpp"
#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::node;
using codec::Volume;

namespace {

// A head-like phantom in LPS voxel order (x to the left, y posterior, z superior), anisotropic:
// an ellipsoid, a nose at the front, a bright block near the patient's left ear and a crown on
// top, so that any flip or swap of axes changes the picture.
Volume phantom(bool markerOnly = false) {
  Volume v = Volume::allocate({22, 26, 18}, codec::ScalarType::Int16, {1.0, 0.8, 1.25});
  auto values = v.as<std::int16_t>();
  for (int z = 0; z < v.dims.z; ++z)
    for (int y = 0; y < v.dims.y; ++y)
      for (int x = 0; x < v.dims.x; ++x) {
        const double dx = (x - 10.5) / 8.0, dy = (y - 12.5) / 10.0, dz = (z - 8.0) / 7.0;
        int value = 0;
        if (!markerOnly && dx * dx + dy * dy + dz * dz < 1) value = 60 + 2 * z;
        if (!markerOnly && y < 4 && std::abs(x - 10) < 2 && std::abs(z - 8) < 2) value = 120;
        if (!markerOnly && z > 14 && std::abs(x - 10) < 3 && y > 9 && y < 16) value = 150;
        if (x >= 17 && x <= 19 && y >= 10 && y <= 14 && z >= 7 && z <= 10) value = 250;
        values[v.index(x, y, z)] = std::int16_t(value);
      }
  v.computeRange();
  return v;
}

// `p` (LPS order) stored with its axes along `letters` (e.g. "RAS": x to the right): the voxels
// reordered, the spacing permuted and the orientation saying where they lie, so that every voxel
// keeps its place in the patient.
Volume stored(const Volume& p, const std::string& letters) {
  const glm::dmat3 d = codec::parseOrientationLetters(letters);
  int axis[3];
  bool flip[3];
  glm::ivec3 dims;
  glm::dvec3 spacing;
  for (int a = 0; a < 3; ++a) {
    for (int r = 0; r < 3; ++r)
      if (d[a][r] != 0) axis[a] = r, flip[a] = d[a][r] < 0;
    dims[a] = p.dims[axis[a]];
    spacing[a] = p.spacing[axis[a]];
  }
  Volume q = Volume::allocate(dims, p.type, spacing);
  const auto source = [&](glm::ivec3 qi) {
    glm::ivec3 pi;
    for (int a = 0; a < 3; ++a) pi[axis[a]] = flip[a] ? dims[a] - 1 - qi[a] : qi[a];
    return pi;
  };
  auto out = q.as<std::int16_t>();
  const auto in = p.as<std::int16_t>();
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const glm::ivec3 pi = source({x, y, z});
        out[q.index(x, y, z)] = in[p.index(pi.x, pi.y, pi.z)];
      }
  q.orientation.direction = d;
  q.orientation.origin = p.orientation.origin + glm::dvec3(source({0, 0, 0})) * p.spacing;
  q.computeRange();
  return q;
}

// `v` as a DICOM series: one file per z slice, positioned and oriented as `v` says.
void writeSeries(const Volume& v, const std::string& dir) {
  std::filesystem::create_directories(dir);
  const glm::dmat3& d = v.orientation.direction;
  for (int z = 0; z < v.dims.z; ++z) {
    test::DicomSlice slice;
    slice.columns = v.dims.x, slice.rows = v.dims.y;
    const auto values = v.as<std::int16_t>();
    const std::size_t first = v.index(0, 0, z);
    slice.pixels.assign(values.begin() + std::ptrdiff_t(first),
                        values.begin() + std::ptrdiff_t(first + std::size_t(v.dims.x * v.dims.y)));
    slice.orientation = {d[0].x, d[0].y, d[0].z, d[1].x, d[1].y, d[1].z};
    slice.position = v.orientation.origin + d[2] * (v.spacing.z * z);
    slice.pixelSpacing = {v.spacing.x, v.spacing.y};
    slice.instance = z + 1;
    test::writeDicom(dir + "/slice" + std::to_string((z * 7) % v.dims.z), slice);
  }
}

Image render(const Volume& v, const Orbit& orbit) {
  const RenderVolume volume = RenderVolume::fromVolume(v, 8);
  const Camera camera = orbitCamera(orbit, boundingRadius(volume.info()));
  const auto tf = TransferFunction::preset("grey").rescaled(0, 250);
  const auto plan = planFrame(volume, camera, 96, 72, tf, {});
  Image image;
  makeCpuBackend(2)->render(volume, plan, {0, 0, 96, 72}, image);
  return image;
}

Orbit view(const char* name) {
  Orbit o;
  const auto angles = anatomicalView(name);
  if (angles) o.azimuthDeg = angles->azimuthDeg, o.elevationDeg = angles->elevationDeg;
  return o;
}

// The column of the picture's brightness centre (of pixels above the background).
double brightColumn(const Image& image) {
  double sum = 0, weight = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const std::uint32_t p = image.at(x, y);
      const double w = double(p & 0xff) + double((p >> 8) & 0xff) + double((p >> 16) & 0xff);
      sum += w * x, weight += w;
    }
  return weight > 0 ? sum / weight : -1;
}

}  // namespace

TEST(Orientation, TheSameScanFromEveryFormatRendersTheSamePicture) {
  test::TempDir dir;
  const Volume lps = phantom();
  codec::writeVolume(stored(lps, "RAS"), dir.path("ras.nii.gz"));
  codec::writeVolume(stored(lps, "LAS"), dir.path("las.nii"));
  codec::writeVolume(stored(lps, "SLA"), dir.path("sla.nrrd"));
  writeSeries(stored(lps, "RAI"), dir.path("dicom"));
  struct Variant {
    const char* name;
    Volume volume;
  };
  std::vector<Variant> variants;
  for (const char* file : {"ras.nii.gz", "las.nii", "sla.nrrd", "dicom"})
    variants.push_back({file, codec::readVolume(dir.path(file))});
  EXPECT_EQ(codec::orientationLetters(variants[0].volume.orientation.direction), "RAS");
  EXPECT_EQ(codec::orientationLetters(variants[2].volume.orientation.direction), "SLA");
  // The series was written slice by slice going inferior, but a DICOM reader sorts the slices
  // along row x column (here superior): the voxels come back in RAS order.
  EXPECT_EQ(codec::orientationLetters(variants[3].volume.orientation.direction), "RAS");

  Orbit oblique;
  oblique.azimuthDeg = -60, oblique.elevationDeg = 25;
  for (const Orbit& orbit : {view("anterior"), view("left"), view("inferior"), oblique}) {
    const Image reference = render(lps, orbit);
    for (const Variant& v : variants) {
      SCOPED_TRACE(std::string(v.name) + " at azimuth " + std::to_string(orbit.azimuthDeg) +
                   ", elevation " + std::to_string(orbit.elevationDeg));
      test::expectImagesNear(reference, render(v.volume, orbit), 255, 40.0,
                             std::string("orientation-") + v.name);
    }
  }
  // The test can fail: the RAS file rendered as if it were LPS (its orientation dropped) is
  // the mirrored picture.
  Volume ignored = variants[0].volume;
  ignored.orientation = {};
  const Image mirrored = render(ignored, view("anterior"));
  const Image reference = render(lps, view("anterior"));
  double error = 0;
  for (std::size_t i = 0; i < reference.pixels.size(); ++i)
    for (int shift = 0; shift < 24; shift += 8)
      error += std::abs(int((reference.pixels[i] >> shift) & 0xff) -
                        int((mirrored.pixels[i] >> shift) & 0xff));
  EXPECT_GT(error / (3.0 * double(reference.pixels.size())), 1.0);
}

// Facing the patient (anterior view), the patient's left is on the picture's right; from behind
// it is on the left; from the feet (inferior, anterior up) on the right again.
TEST(Orientation, TheLeftMarkerShowsOnTheRightInAnAnteriorView) {
  test::TempDir dir;
  const Volume marker = phantom(true);
  codec::writeVolume(stored(marker, "RAS"), dir.path("ras.nii"));
  const Volume ras = codec::readVolume(dir.path("ras.nii"));
  for (const Volume* v : {&marker, &ras}) {
    const Image anterior = render(*v, view("anterior"));
    ASSERT_GT(brightColumn(anterior), 0) << "the marker is not on the picture";
    EXPECT_GT(brightColumn(anterior), anterior.width * 0.6);
    EXPECT_LT(brightColumn(render(*v, view("posterior"))), anterior.width * 0.4);
    EXPECT_GT(brightColumn(render(*v, view("inferior"))), anterior.width * 0.6);
  }
}
