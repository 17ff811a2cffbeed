// The frames a render job writes to --out: the job manifest (voxwall-job.json: the settings and
// each finished frame's size and hash), --resume's choice of the frames to keep, and the writer
// thread.
#include "frame_output.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>
#include <voxwall/core/text.hpp>

namespace voxwall::master {
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

constexpr const char* kManifestName = "voxwall-job.json";

void writeManifest(const std::string& outDir, const nlohmann::json& manifest) {
  const std::string text = manifest.dump(2) + "\n";
  voxwall::writeFileAtomically((fs::path(outDir) / kManifestName).string(),
                               std::as_bytes(std::span(text)));
}

}  // namespace

FrameWriter::FrameWriter(std::string outDir, nlohmann::json manifest)
    : outDir_(std::move(outDir)), manifest_(std::move(manifest)) {}

double FrameWriter::push(voxwall::Image image, std::string path,
                         std::optional<glm::dvec3> background) {
  const double wait = finish();
  pending_ = std::async(std::launch::async,
                        [this, image = std::move(image), path = std::move(path), background]() {
                          const auto start = Clock::now();
                          const auto digest = voxwall::writeImage(image, path, background);
                          manifest_["completed"][fs::path(path).filename().string()] = {
                              {"bytes", digest.bytes}, {"xxh64", voxwall::hex64(digest.xxh64)}};
                          writeManifest(outDir_, manifest_);
                          return since(start);
                        });
  return wait;
}

double FrameWriter::finish() {
  if (!pending_.valid()) return 0;
  const auto start = Clock::now();
  totalWriteSeconds_ += pending_.get();
  return since(start);
}

FrameWriter::~FrameWriter() {
  if (pending_.valid()) pending_.wait();
}

std::string framePath(const JobSettings& job, int frame) {
  char name[64];
  std::snprintf(name, sizeof name, "frame_%05d.%s", frame, job.format.c_str());
  return (fs::path(job.outDir) / name).string();
}

namespace {

// --resume: the completed frames a manifest from an earlier run of the same settings recorded
// (its "completed"); refuses a folder of frames made otherwise, or without a manifest.
nlohmann::json recordedFrames(const JobSettings& job, const fs::path& manifestPath,
                              const nlohmann::json& wanted) {
  std::error_code ec;
  int existing = 0;
  for (int f = 0; f < job.frames; ++f) existing += fs::exists(framePath(job, f), ec);
  if (!fs::exists(manifestPath)) {
    if (existing > 0)
      throw FormatError(job.outDir, "holds frames but no " + std::string(kManifestName) +
                                        ": cannot tell how they were made; use another --out or "
                                        "drop --resume");
    return nlohmann::json::object();
  }
  nlohmann::json found, frames = nlohmann::json::object();
  try {
    std::ifstream in(manifestPath);
    found = nlohmann::json::parse(in);
    if (found.contains("completed")) {
      frames = found["completed"];
      found.erase("completed");
    }
    if (!frames.is_object())
      throw FormatError(manifestPath.string(), "'completed' is not an object");
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(manifestPath.string(), std::string("not valid JSON: ") + e.what());
  }
  if (found != wanted) {
    std::string differs;
    for (const auto& [key, value] : wanted.items())
      if (!found.contains(key) || found[key] != value)
        differs += (differs.empty() ? "" : ", ") + key;
    throw FormatError(manifestPath.string(),
                      "the frames here were rendered with other settings (" +
                          (differs.empty() ? std::string("extra keys") : differs) +
                          "); use another --out or drop --resume to overwrite them");
  }
  return frames;
}

// Of the recorded frames, those whose file still has the size and hash the manifest recorded
// (marked in `done`): a frame cut short by a full disk, or changed since, is rendered again.
nlohmann::json keptFrames(const JobSettings& job, const nlohmann::json& frames,
                          std::vector<bool>& done) {
  nlohmann::json kept = nlohmann::json::object();
  for (int f = 0; f < job.frames; ++f) {
    const std::string path = framePath(job, f);
    const std::string name = fs::path(path).filename().string();
    if (!frames.contains(name)) continue;
    bool same = false;
    try {
      same = voxwall::fileHasDigest(path, frames[name].at("bytes").get<std::uint64_t>(),
                                    frames[name].at("xxh64").get<std::string>());
    } catch (const nlohmann::json::exception&) {
    }
    if (same) {
      done[std::size_t(f)] = true;
      kept[name] = frames[name];
    } else {
      std::fprintf(stderr, "voxwall: %s: not as the job manifest recorded it; rendering it again\n",
                   path.c_str());
    }
  }
  return kept;
}

}  // namespace

std::vector<bool> prepareOutput(const JobSettings& job, nlohmann::json* manifest) {
  std::vector<bool> done(std::size_t(job.frames), false);
  if (job.outDir.empty()) return done;
  std::error_code ec;
  fs::create_directories(job.outDir, ec);
  if (ec) throw FormatError(job.outDir, "cannot create output directory: " + ec.message());
  const auto wanted = nlohmann::json::parse(job.manifest);
  nlohmann::json frames = nlohmann::json::object();
  if (job.resume) {
    // Temporaries of frames that were being written when the last run was killed.
    for (const auto& entry : fs::directory_iterator(job.outDir, ec)) {
      const auto name = entry.path().filename().string();
      if ((name.rfind("frame_", 0) == 0 || name.rfind(kManifestName, 0) == 0) &&
          name.find(".tmp.") != std::string::npos)
        fs::remove(entry.path(), ec);
    }
    frames =
        keptFrames(job, recordedFrames(job, fs::path(job.outDir) / kManifestName, wanted), done);
  }
  nlohmann::json out = wanted;
  out["completed"] = frames;
  writeManifest(job.outDir, out);
  if (manifest) *manifest = out;
  return done;
}

std::vector<bool> prepareOutput(const JobSettings& job) { return prepareOutput(job, nullptr); }

}  // namespace voxwall::master
