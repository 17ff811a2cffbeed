#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/files.hpp>
#include <voxwall/core/parallel.hpp>
#include <voxwall/walls/frame_files.hpp>
#include <voxwall/walls/frame_pixels.hpp>

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

const char* frameFileExtension(FrameFormat format) {
  return format == FrameFormat::Jpeg ? ".jpg" : ".png";
}

void writeFrameFiles(const std::string& dir, const Wall& wall, const AssembledFrame& frame,
                     const FrameFileSettings& settings) {
  const std::string stem = frameStem(frame.frame);
  struct Picture {
    std::string path;
    voxwall::Rect region;
    std::vector<std::byte> bytes;
  };
  std::vector<Picture> pictures;
  // The mosaic first: it is the biggest job, and the others fill the threads around it.
  if (settings.mosaic)
    pictures.push_back(
        {(fs::path(dir) / (stem + "_mosaic.png")).string(), {0, 0, wall.width, wall.height}, {}});
  for (const auto& d : wall.displays)
    pictures.push_back(
        {(fs::path(dir) / (stem + "_" + d.name + frameFileExtension(settings.format))).string(),
         d.rect,
         {}});
  const std::uint32_t fill = backgroundPixel(wall.background);
  voxwall::parallelFor(pictures.size(), settings.threads, [&](std::size_t i) {
    auto& p = pictures[i];
    voxwall::Image pixels;
    try {
      pixels = decodeRegion(frame, p.region, 1, fill, 1);
    } catch (const FormatError& e) {
      throw UndecodableFrame("", e.what());
    }
    p.bytes = voxwall::encodeOpaqueImage(pixels, p.path, settings.encoding);
  });
  std::vector<std::pair<std::string, std::string>> written;  // temporary, final
  nlohmann::json files = nlohmann::json::object();
  auto undo = [&] {
    std::error_code ignored;
    for (const auto& [tmp, path] : written) fs::remove(tmp, ignored), fs::remove(path, ignored);
  };
  try {
    for (const auto& p : pictures) {
      written.emplace_back(voxwall::writeTemporary(p.path, p.bytes), p.path);
      const auto digest = voxwall::digestOf(p.bytes);
      files[fs::path(p.path).filename().string()] = {{"bytes", digest.bytes},
                                                     {"xxh64", voxwall::hex64(digest.xxh64)}};
    }
    for (const auto& [tmp, path] : written) voxwall::commitTemporary(tmp, path);
    const std::string marker =
        nlohmann::json{{"frame", frame.frame}, {"wall", wall.id}, {"files", files}}.dump(2) + "\n";
    voxwall::writeFileAtomically(frameMarkerPath(dir, frame.frame),
                                 std::as_bytes(std::span(marker)));
  } catch (...) {
    undo();
    throw;
  }
}

FrameFileWriter::FrameFileWriter(std::string dir, Wall wall, FrameFileSettings settings, int queue,
                                 Events events)
    : dir_(std::move(dir)),
      wall_(std::move(wall)),
      settings_(settings),
      queue_(std::size_t(std::max(1, queue))),
      events_(std::move(events)) {
  thread_ = std::thread([this] { run(); });
}

FrameFileWriter::~FrameFileWriter() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void FrameFileWriter::push(std::uint64_t job, std::shared_ptr<const AssembledFrame> frame) {
  std::optional<std::pair<std::uint64_t, std::shared_ptr<const AssembledFrame>>> pushedOut;
  {
    std::lock_guard lock(mutex_);
    if (failed_) return;
    if (waiting_.size() >= queue_) {
      pushedOut = std::move(waiting_.front());
      waiting_.pop_front();
    }
    waiting_.emplace_back(job, std::move(frame));
  }
  changed_.notify_all();
  if (pushedOut && events_)
    events_(pushedOut->first, pushedOut->second->frame, Outcome::Skipped,
            "not written: the file writer fell behind");
}

void FrameFileWriter::drain() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return failed_ || (waiting_.empty() && !busy_); });
}

void FrameFileWriter::run() {
  for (;;) {
    std::pair<std::uint64_t, std::shared_ptr<const AssembledFrame>> next;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return stop_ || !waiting_.empty(); });
      if (waiting_.empty() || failed_) return;  // stopping, with everything written
      next = std::move(waiting_.front());
      waiting_.pop_front();
      busy_ = true;
    }
    Outcome outcome = Outcome::Written;
    std::string why;
    try {
      writeFrameFiles(dir_, wall_, *next.second, settings_);
    } catch (const UndecodableFrame& e) {
      outcome = Outcome::Skipped;
      why = std::string("not written: ") + e.what();
    } catch (const std::exception& e) {
      outcome = Outcome::Failed;
      why = e.what();
    }
    {
      std::lock_guard lock(mutex_);
      busy_ = false;
      if (outcome == Outcome::Failed) failed_ = true, waiting_.clear();
    }
    changed_.notify_all();
    if (events_) events_(next.first, next.second->frame, outcome, why);
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
    else if (next == '_' && (name.ends_with(".png") || name.ends_with(".jpg")))
      pictures.emplace_back(*frame, entry.path());
  }
  for (const auto& [frame, path] : pictures)
    if (!marked.count(frame)) doomed.push_back(path);
  int removed = 0;
  for (const auto& path : doomed) removed += fs::remove(path, ec) ? 1 : 0;
  return removed;
}

}  // namespace voxwall::walls
