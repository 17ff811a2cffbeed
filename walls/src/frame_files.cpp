#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>
#include <voxwall/walls/frame_files.hpp>

namespace voxwall::walls {
namespace fs = std::filesystem;

namespace {

// "frame_00012_r0c1.png" -> 12 (and '_', the character after the number); nullopt for names
// that are not a frame's.
std::optional<std::uint64_t> frameOf(const std::string& name, char* next) {
  if (name.rfind("frame_", 0) != 0) return std::nullopt;
  std::uint64_t frame = 0;
  const char* begin = name.data() + 6;
  const char* last = name.data() + name.size();
  const auto [end, ec] = std::from_chars(begin, last, frame);
  if (ec != std::errc() || end == begin || end == last) return std::nullopt;
  *next = *end;
  return frame;
}

}  // namespace

std::string frameStem(std::uint64_t frame) {
  char stem[40];
  std::snprintf(stem, sizeof stem, "frame_%05llu", static_cast<unsigned long long>(frame));
  return stem;
}

std::string frameMarkerPath(const std::string& dir, std::uint64_t frame) {
  return (fs::path(dir) / (frameStem(frame) + ".done")).string();
}

void writeFrameFiles(const std::string& dir, std::uint64_t frame, const Wall& wall,
                     const voxwall::Image& screen, bool mosaic) {
  const std::string stem = frameStem(frame);
  std::vector<std::pair<std::string, voxwall::Image>> pictures;
  for (const auto& d : wall.displays)
    pictures.emplace_back((fs::path(dir) / (stem + "_" + d.name + ".png")).string(),
                          screen.crop(d.rect));
  std::vector<std::pair<std::string, std::string>> written;  // temporary, final
  nlohmann::json files = nlohmann::json::object();
  auto undo = [&] {
    std::error_code ignored;
    for (const auto& [tmp, path] : written) fs::remove(tmp, ignored), fs::remove(path, ignored);
  };
  try {
    auto add = [&](const std::string& path, const voxwall::Image& image) {
      const auto bytes = voxwall::encodeImage(image, path);
      written.emplace_back(voxwall::writeTemporary(path, bytes), path);
      const auto digest = voxwall::digestOf(bytes);
      files[fs::path(path).filename().string()] = {{"bytes", digest.bytes},
                                                   {"xxh64", voxwall::hex64(digest.xxh64)}};
    };
    for (const auto& [path, image] : pictures) add(path, image);
    if (mosaic) add((fs::path(dir) / (stem + "_mosaic.png")).string(), screen);
    for (const auto& [tmp, path] : written) voxwall::commitTemporary(tmp, path);
    const std::string marker =
        nlohmann::json{{"frame", frame}, {"wall", wall.id}, {"files", files}}.dump(2) + "\n";
    voxwall::writeFileAtomically(frameMarkerPath(dir, frame), std::as_bytes(std::span(marker)));
  } catch (...) {
    undo();
    throw;
  }
}

bool frameFilesComplete(const std::string& dir, std::uint64_t frame) {
  nlohmann::json marker;
  try {
    std::ifstream in(frameMarkerPath(dir, frame));
    if (!in) return false;
    marker = nlohmann::json::parse(in);
    for (const auto& [name, want] : marker.at("files").items())
      if (!voxwall::fileHasDigest((fs::path(dir) / name).string(),
                                  want.at("bytes").get<std::uint64_t>(),
                                  want.at("xxh64").get<std::string>()))
        return false;
  } catch (const nlohmann::json::exception&) {
    return false;
  }
  return true;
}

int removeIncompleteFrames(const std::string& dir) {
  std::error_code ec;
  std::vector<fs::path> doomed;
  std::set<std::uint64_t> marked;
  std::vector<std::pair<std::uint64_t, fs::path>> pictures;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    char next = 0;
    const auto frame = frameOf(name, &next);
    if (!frame) continue;
    // Only a sink's files: "frame_N_<display>.png", not a render job's "frame_N.png".
    if (name.find(".tmp.") != std::string::npos) {
      if (next == '_' || name.find(".done.tmp.") != std::string::npos)
        doomed.push_back(entry.path());
    } else if (next == '.' && name.ends_with(".done"))
      marked.insert(*frame);
    else if (next == '_' && name.ends_with(".png"))
      pictures.emplace_back(*frame, entry.path());
  }
  for (const auto& [frame, path] : pictures)
    if (!marked.count(frame)) doomed.push_back(path);
  int removed = 0;
  for (const auto& path : doomed) removed += fs::remove(path, ec) ? 1 : 0;
  return removed;
}

}  // namespace voxwall::walls
