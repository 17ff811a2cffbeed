#include <gtest/gtest.h>
#include <xxhash.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/generators.hpp>
#include <voxwall/codec/raw_bricks.hpp>
#include <voxwall/core/errors.hpp>

#include "support/temp_dir.hpp"

using namespace voxwall;
using namespace voxwall::codec;

namespace {

CompressedVolume sample() {
  Volume v = generateMarschnerLobb(11, ScalarType::UInt16);
  Progress quiet;
  return rawbricks::encode(v, {4}, quiet);
}

std::string parseError(const std::vector<std::byte>& bytes) {
  try {
    ContainerFile::parse(bytes, "test.vwz");
  } catch (const FormatError& e) {
    return e.what();
  }
  return "";
}

// Recomputes the table and header checksums, so a test can forge a file whose checksums are
// right but whose fields are not.
void reseal(std::vector<std::byte>& bytes) {
  std::uint32_t sections;
  std::memcpy(&sections, bytes.data() + 36, 4);
  const std::uint64_t table = XXH64(bytes.data() + 128, 32 * std::size_t(sections), 0);
  std::memcpy(bytes.data() + 88, &table, 8);
  const std::uint64_t header = XXH64(bytes.data(), 120, 0);
  std::memcpy(bytes.data() + 120, &header, 8);
}

}  // namespace

TEST(Container, RoundTripsHeaderAndSections) {
  const auto c = sample();
  const auto bytes = serializeContainer(c);
  const auto file = ContainerFile::parse(bytes, "mem");
  EXPECT_EQ(file.info().dims, c.info.dims);
  EXPECT_EQ(file.info().type, ScalarType::UInt16);
  EXPECT_EQ(file.info().codec, rawbricks::kCodecId);
  EXPECT_EQ(file.info().valueMax, c.info.valueMax);
  ASSERT_EQ(file.sections().sections.size(), c.sections.size());
  for (auto& [id, data] : c.sections) {
    auto s = file.sections().get(id, "x");
    EXPECT_EQ(std::vector<std::byte>(s.begin(), s.end()), data);
    EXPECT_EQ(std::size_t(s.data() - bytes.data()) % kSectionAlignment, 0u);
  }
}

TEST(Container, FileRoundTripIsMemoryMapped) {
  test::TempDir dir;
  const auto c = sample();
  const std::uint64_t written = writeContainer(c, dir.path("a.vwz"));
  EXPECT_TRUE(isContainerFile(dir.path("a.vwz")));
  const auto file = ContainerFile::open(dir.path("a.vwz"));
  // Written piece by piece, the file is byte for byte what serializeContainer joins.
  const auto joined = serializeContainer(c);
  EXPECT_EQ(file.fileBytes(), joined.size());
  EXPECT_EQ(written, file.fileBytes());
  const std::string onDisk = test::readFile(dir.path("a.vwz"));
  ASSERT_EQ(onDisk.size(), joined.size());
  EXPECT_EQ(std::memcmp(onDisk.data(), joined.data(), joined.size()), 0);
  const Volume back = rawbricks::decode(file.info(), file.sections());
  EXPECT_EQ(back.dims, c.info.dims);
}

// The process's resident memory in bytes (VmRSS).
std::uint64_t residentBytes() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (!f) return 0;
  char line[256];
  unsigned long long kib = 0;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "VmRSS: %llu kB", &kib) == 1) break;
  std::fclose(f);
  return kib * 1024;
}

// Opening reads every byte (the checksums); releasing drops the mapping from the resident set,
// and the sections still read the same bytes.
TEST(Container, ReleasingTheMappingDropsItFromResidentMemory) {
  test::TempDir dir;
  CompressedVolume c;
  c.info.dims = {256, 256, 256};
  std::vector<std::byte> data(std::size_t(32) << 20);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = std::byte(i * 2654435761u >> 24);
  c.sections.emplace_back(7, data);
  writeContainer(c, dir.path("big.vwz"));
  const auto file = ContainerFile::open(dir.path("big.vwz"));
  const std::uint64_t opened = residentBytes();
  file.releaseResident();
  const std::uint64_t released = residentBytes();
  if (opened == 0) GTEST_SKIP() << "no /proc/self/status here";
  EXPECT_LT(released + (std::uint64_t(16) << 20), opened)
      << "opened " << opened << " bytes resident, after release " << released;
  const auto s = file.sections().get(7, "data");
  ASSERT_EQ(s.size(), data.size());
  EXPECT_EQ(std::memcmp(s.data(), data.data(), data.size()), 0);
}

TEST(Container, DetectsAFlippedByteAnywhere) {
  const auto good = serializeContainer(sample());
  // Every byte of the header and table, and a byte in every section.
  std::vector<std::size_t> positions;
  for (std::size_t i = 0; i < 128 + 32 * 4; ++i) positions.push_back(i);
  // The container's own orientation section (the last entry) too.
  std::uint64_t orientationAt = 0;
  std::memcpy(&orientationAt, good.data() + 128 + 32 * 3 + 8, 8);
  for (std::size_t i = 0; i < 96; i += 8) positions.push_back(std::size_t(orientationAt) + i);
  const auto file = ContainerFile::parse(good, "mem");
  for (auto& [id, span] : file.sections().sections) {
    const std::size_t off = std::size_t(span.data() - good.data());
    positions.push_back(off);
    positions.push_back(off + span.size() / 2);
    positions.push_back(off + span.size() - 1);
  }
  for (std::size_t pos : positions) {
    auto bad = good;
    bad[pos] ^= std::byte{0x10};
    const std::string err = parseError(bad);
    EXPECT_FALSE(err.empty()) << "flipped byte at " << pos << " went unnoticed";
    EXPECT_EQ(err.rfind("test.vwz: ", 0), 0u) << err;
  }
}

TEST(Container, RefusesEveryTruncation) {
  const auto good = serializeContainer(sample());
  for (std::size_t n = 0; n < good.size(); n += (n < 300 ? 1 : 97)) {
    std::vector<std::byte> cut(good.begin(), good.begin() + std::ptrdiff_t(n));
    EXPECT_FALSE(parseError(cut).empty()) << "truncated to " << n;
  }
  EXPECT_NE(parseError({good.begin(), good.end() - 1}).find("truncated"), std::string::npos);
}

TEST(Container, RefusesOtherVersionsAndMagic) {
  auto bytes = serializeContainer(sample());
  for (std::uint32_t version : {0u, kContainerVersion + 1, 0xffffffffu}) {
    auto bad = bytes;
    std::memcpy(bad.data() + 8, &version, 4);
    reseal(bad);  // only the version is wrong
    EXPECT_NE(parseError(bad).find("version"), std::string::npos) << version;
  }
  auto bad = bytes;
  bad[0] = std::byte{'X'};
  EXPECT_NE(parseError(bad).find("magic"), std::string::npos);
}

TEST(Container, RefusesASectionLengthPastTheEnd) {
  auto bytes = serializeContainer(sample());
  const std::uint64_t huge = 1ull << 62;
  std::memcpy(bytes.data() + 128 + 32 * 2 + 16, &huge, 8);  // length of the third section
  reseal(bytes);
  EXPECT_NE(parseError(bytes).find("past the end"), std::string::npos) << parseError(bytes);
}

TEST(Container, RefusesOverlappingAndMisalignedSections) {
  const auto good = serializeContainer(sample());
  auto overlap = good;
  std::uint64_t offset;
  std::memcpy(&offset, good.data() + 128 + 8, 8);          // first section's offset
  std::memcpy(overlap.data() + 128 + 32 + 8, &offset, 8);  // second section starts there too
  reseal(overlap);
  EXPECT_NE(parseError(overlap).find("overlaps"), std::string::npos) << parseError(overlap);
  auto misaligned = good;
  offset += 8;
  std::memcpy(misaligned.data() + 128 + 8, &offset, 8);
  reseal(misaligned);
  EXPECT_NE(parseError(misaligned).find("aligned"), std::string::npos) << parseError(misaligned);
  auto many = good;
  const std::uint32_t count = 1000;
  std::memcpy(many.data() + 36, &count, 4);
  const std::uint64_t header = XXH64(many.data(), 120, 0);
  std::memcpy(many.data() + 120, &header, 8);
  EXPECT_NE(parseError(many).find("section count"), std::string::npos) << parseError(many);
}

// The orientation goes through the file as it is, mirror and origin included.
TEST(Container, OrientationRoundTrips) {
  auto c = sample();
  c.info.orientation.direction = glm::dmat3(glm::dvec3(0, -1, 0), glm::dvec3(0, 0, -1),
                                            glm::dvec3(-1, 0, 0));  // x to A, y to I, z to R
  c.info.orientation.origin = {12.5, -40, 7.25};
  const auto bytes = serializeContainer(c);
  const auto file = ContainerFile::parse(bytes, "mem");
  EXPECT_EQ(file.version(), kSingleVolumeVersion);
  EXPECT_EQ(file.info().orientation, c.info.orientation);
  EXPECT_EQ(orientationLetters(file.info().orientation.direction), "AIR");
  // The codec sees only its own sections.
  EXPECT_EQ(file.sections().sections.size(), c.sections.size());
}

TEST(Container, RefusesADirectionThatIsNotARotation) {
  auto c = sample();
  c.info.orientation.direction[1] = glm::dvec3(0.5, 0.5, 0);  // not unit, not orthogonal to x
  EXPECT_NE(parseError(serializeContainer(c)).find("invalid orientation"), std::string::npos)
      << parseError(serializeContainer(c));
  c = sample();
  c.info.orientation.origin.x = std::nan("");
  EXPECT_NE(parseError(serializeContainer(c)).find("origin is not finite"), std::string::npos);
}

// A file of format version 1 (before orientation) still opens, as LPS; a version 2 file without
// its orientation section does not.
TEST(Container, VersionOneFilesOpenWithTheIdentityOrientation) {
  auto c = sample();
  c.info.orientation.origin = {1, 2, 3};
  const auto v2 = serializeContainer(c);
  std::uint64_t orientationAt = 0;
  std::memcpy(&orientationAt, v2.data() + 128 + 32 * 3 + 8, 8);
  // Version 1: three sections, the file ending where the codec's last section ends.
  std::vector<std::byte> v1(v2.begin(), v2.begin() + std::ptrdiff_t(7198));
  const std::uint32_t one = 1, three = 3;
  const std::uint64_t size = v1.size();
  std::memcpy(v1.data() + 8, &one, 4);
  std::memcpy(v1.data() + 36, &three, 4);
  std::memcpy(v1.data() + 80, &size, 8);
  reseal(v1);
  const auto file = ContainerFile::parse(v1, "old.vwz");
  EXPECT_EQ(file.version(), 1u);
  EXPECT_EQ(file.info().orientation, Orientation{});
  EXPECT_EQ(file.sections().sections.size(), 3u);
  EXPECT_EQ(orientationAt, 7232u);  // the orientation section follows the codec's, aligned

  auto stripped = v1;
  const std::uint32_t two = 2;
  std::memcpy(stripped.data() + 8, &two, 4);
  reseal(stripped);
  EXPECT_NE(parseError(stripped).find("orientation section is missing"), std::string::npos)
      << parseError(stripped);
}

TEST(Container, MissingFileGivesOneLine) {
  try {
    ContainerFile::open("/nonexistent/x.vwz");
    FAIL();
  } catch (const FormatError& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/x.vwz: No such file or directory");
  }
}

// The bytes of a small raw-coded file are pinned: a change to the layout must be deliberate
// (bump kContainerVersion and update this checksum).
TEST(Container, GoldenChecksumOfASmallFile) {
  const auto bytes = serializeContainer(sample());
  // 128-byte header + 4 table entries -> 256; params (8) -> 320; 27 range cells of two uint16
  // (108) -> 448; 27 bricks of 4^3 uint16 stored with their apron as 5^3 (6750) -> 7198;
  // the orientation (96) at 7232 -> 7328.
  EXPECT_EQ(bytes.size(), 7328u);
  EXPECT_EQ(XXH64(bytes.data(), bytes.size(), 0), 0x26e1c353ba24dd46ull)
      << std::hex << XXH64(bytes.data(), bytes.size(), 0);
}

namespace {

// Three steps of a small volume, each coded on its own: step 2 scaled so its range differs.
std::vector<CompressedVolume> sampleSteps() {
  std::vector<CompressedVolume> steps;
  Progress quiet;
  for (int k = 0; k < 3; ++k) {
    Volume v = generateMarschnerLobb(11, ScalarType::UInt16);
    auto voxels = v.as<std::uint16_t>();
    for (std::size_t i = 0; i < voxels.size(); ++i)
      voxels[i] = std::uint16_t(voxels[i] / (k + 1) + (i % 7 == 0 ? k : 0));
    v.computeRange();
    steps.push_back(rawbricks::encode(v, {4}, quiet));
  }
  return steps;
}

}  // namespace

// A series stores each step's own sections and, once, those every step has alike (the raw
// codec's params); each step reads as the volume it was.
TEST(ContainerSeries, StepsRoundTripWithIdenticalSectionsStoredOnce) {
  const auto steps = sampleSteps();
  const CompressedSeries series = makeSeries(steps);
  ASSERT_EQ(series.shared.size(), 1u);  // the params (8 bytes); ranges and bricks differ
  EXPECT_EQ(series.shared.front().first, 1u);
  const auto bytes = serializeContainer(series);
  const auto file = ContainerFile::parse(bytes, "series.vwz");
  EXPECT_EQ(file.version(), kContainerVersion);
  ASSERT_EQ(file.stepCount(), 3);
  EXPECT_EQ(file.info().steps, 3);
  EXPECT_EQ(file.sharedBytes(), 8u);
  double lo = 1e300, hi = -1e300;
  for (int k = 0; k < 3; ++k) {
    const VolumeInfo info = file.stepInfo(k);
    EXPECT_EQ(info.steps, 1);
    EXPECT_EQ(info.valueMin, steps[std::size_t(k)].info.valueMin);
    EXPECT_EQ(info.valueMax, steps[std::size_t(k)].info.valueMax);
    lo = std::min(lo, info.valueMin), hi = std::max(hi, info.valueMax);
    ASSERT_EQ(file.stepSections(k).sections.size(), steps[std::size_t(k)].sections.size());
    for (const auto& [id, data] : steps[std::size_t(k)].sections) {
      const auto got = file.stepSections(k).get(id, "x");
      EXPECT_EQ(std::vector<std::byte>(got.begin(), got.end()), data) << "step " << k;
    }
    const Volume back = rawbricks::decode(file.stepInfo(k), file.stepSections(k));
    const Volume want = rawbricks::decode(steps[std::size_t(k)].info, steps[std::size_t(k)].view());
    EXPECT_EQ(back.data, want.data) << "step " << k;
  }
  EXPECT_EQ(file.info().valueMin, lo);  // the header holds the whole series' range
  EXPECT_EQ(file.info().valueMax, hi);
  EXPECT_NE(file.stepInfo(0).valueMax, file.stepInfo(1).valueMax);
  // The shared params are in no step's bytes.
  std::uint64_t own = 0;
  for (int k = 0; k < 3; ++k) own += file.stepBytes(k);
  EXPECT_EQ(own + file.sharedBytes(), series.payloadBytes());
}

// A series of one step is a plain version 2 file, which earlier builds read.
TEST(ContainerSeries, OneStepIsAVersionTwoFile) {
  auto steps = sampleSteps();
  steps.resize(1);
  const auto bytes = serializeContainer(makeSeries(steps));
  EXPECT_EQ(bytes, serializeContainer(steps.front()));
  EXPECT_EQ(ContainerFile::parse(bytes, "one.vwz").version(), kSingleVolumeVersion);
}

TEST(ContainerSeries, RefusesStepsThatDiffer) {
  auto steps = sampleSteps();
  Progress quiet;
  steps.push_back(rawbricks::encode(generateMarschnerLobb(12, ScalarType::UInt16), {4}, quiet));
  try {
    (void)makeSeries(steps);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("step 3 differs"), std::string::npos) << e.what();
  }
}

// A flipped byte in a step's section is refused in one line that names the step.
TEST(ContainerSeries, ACorruptStepSectionIsRefusedNamingTheStep) {
  const auto good = serializeContainer(makeSeries(sampleSteps()));
  // The table's 8th entry: step 2's second own section (shared params, then 2 per step).
  std::uint32_t step = 0;
  std::uint64_t offset = 0;
  std::memcpy(&step, good.data() + 128 + 32 * 6 + 4, 4);
  std::memcpy(&offset, good.data() + 128 + 32 * 6 + 8, 8);
  ASSERT_EQ(step, 2u);
  auto bad = good;
  bad[offset + 3] ^= std::byte{0x40};
  const std::string error = parseError(bad);
  EXPECT_NE(error.find("step 2"), std::string::npos) << error;
  EXPECT_NE(error.find("checksum mismatch"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
}

// Forged tables with checksums that fit: a step past the count, a shared id that is also a
// step's own, no step ranges, a step count of zero.
TEST(ContainerSeries, RefusesForgedStepTables) {
  const auto good = serializeContainer(makeSeries(sampleSteps()));
  const std::size_t entry = 128 + 32 * 1 + 4;  // the step of the table's second entry (step 0's)
  auto past = good;
  const std::uint32_t five = 5;
  std::memcpy(past.data() + entry, &five, 4);
  reseal(past);
  EXPECT_NE(parseError(past).find("step 5 is past the file's 3 step(s)"), std::string::npos)
      << parseError(past);

  // Step 1's ranges section (entry 3) made shared: it collides with step 0's own ranges.
  auto collide = good;
  const std::uint32_t shared = kSharedStep;
  std::memcpy(collide.data() + 128 + 32 * 3 + 4, &shared, 4);
  reseal(collide);
  EXPECT_NE(parseError(collide).find("has a section of the same id"), std::string::npos)
      << parseError(collide);

  auto zero = good;
  const std::uint32_t none = 0;
  std::memcpy(zero.data() + 96, &none, 4);
  reseal(zero);
  EXPECT_NE(parseError(zero).find("step count 0"), std::string::npos) << parseError(zero);

  auto more = good;
  const std::uint32_t four = 4;
  std::memcpy(more.data() + 96, &four, 4);
  reseal(more);
  EXPECT_NE(parseError(more).find("step ranges section has 48 bytes, not 16 for each of 4"),
            std::string::npos)
      << parseError(more);
}

// The bytes of a small series are pinned too.
TEST(ContainerSeries, GoldenChecksumOfASmallSeries) {
  const auto bytes = serializeContainer(makeSeries(sampleSteps()));
  EXPECT_EQ(bytes.size(), 21424u);
  EXPECT_EQ(XXH64(bytes.data(), bytes.size(), 0), 0x48de19a8d7cf2b4eull)
      << std::hex << XXH64(bytes.data(), bytes.size(), 0) << " size " << std::dec << bytes.size();
}
