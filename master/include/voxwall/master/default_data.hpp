// The volume the program uses when the user names none.
#pragma once

#include <string>

namespace voxwall::master {

// Debian's mricron-data MRI template (301x370x316 uint8, 0.5 mm), when installed.
inline constexpr const char* kDefaultMriPath = "/usr/share/mricron/templates/ch2better.nii.gz";

// Describes the default volume: the MRI path when it exists, else "generated:shepp-logan:256".
std::string defaultVolumeSpec();

}  // namespace voxwall::master
