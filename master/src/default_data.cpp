#include <filesystem>
#include <voxwall/master/default_data.hpp>

namespace voxwall::master {

std::string defaultVolumeSpec() {
  return std::filesystem::exists(kDefaultMriPath) ? kDefaultMriPath : "generated:shepp-logan:256";
}

}  // namespace voxwall::master
