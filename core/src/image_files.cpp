// Loading the image-file module (voxwall/core/image_files.hpp) on first use.
#include <dlfcn.h>

#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/image_files.hpp>

namespace voxwall::image_files {
namespace {

// Where to look: beside the running program (a copied or installed voxwall carries the module
// next to it), then where this build wrote it.
std::vector<std::string> candidates() {
  std::vector<std::string> out;
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) out.push_back((self.parent_path() / kModuleFile).string());
  out.push_back(VOXWALL_IMAGE_FILES_MODULE);
  return out;
}

}  // namespace

const Api& loadModule(const std::vector<std::string>& paths) {
  std::string tried;
  for (const auto& path : paths) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
      tried += (tried.empty() ? "" : ", ") + path + " (missing)";
      continue;
    }
    void* module = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!module) {
      const char* why = ::dlerror();
      tried += (tried.empty() ? "" : ", ") + path + " (" + (why ? why : "not loadable") + ")";
      continue;
    }
    // Never closed: OpenImageIO keeps its plugins and threads for the life of the process.
    using Entry = const Api* (*)();
    const auto entry = reinterpret_cast<Entry>(::dlsym(module, kEntryPoint));
    const Api* api = entry ? entry() : nullptr;
    if (api && api->version == kApiVersion) return *api;
    tried += (tried.empty() ? "" : ", ") + path +
             (entry ? " (another version of voxwall's)" : " (not voxwall's image-file module)");
  }
  throw std::runtime_error("cannot load voxwall's image-file module " + std::string(kModuleFile) +
                           " (OpenImageIO), needed to read or write images: tried " + tried);
}

const Api& api() {
  // A throw leaves it unset: the next call tries again.
  static const Api& loaded = loadModule(candidates());
  return loaded;
}

Reader::Reader(const std::string& path) : path_(path) {
  std::string error;
  file_ = api().open(path, error);
  if (!file_) throw FormatError(path, error);
}

Reader::~Reader() {
  if (file_) api().close(file_);
}

bool Reader::subimage(int index, Layout& layout) const {
  return api().subimage(file_, index, layout);
}

void Reader::readChannel0(int index, Pixel type, void* dst, const std::string& what) const {
  std::string error;
  if (!api().readChannel0(file_, index, type, dst, error)) throw FormatError(what, error);
}

}  // namespace voxwall::image_files
