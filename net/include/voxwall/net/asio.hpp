// The one way voxwall includes Asio (standalone, header-only).
//
// Asio picks parts of its configuration from macros that libstdc++ defines in <bits/c++config.h>
// (e.g. whether std::aligned_alloc exists, which decides how handler memory is allocated and
// freed). A file that includes <asio.hpp> before any standard header configures Asio differently
// from one that does not, and memory allocated by one file's Asio code is then freed by the
// other's with the wrong function (AddressSanitizer: alloc-dealloc-mismatch in the sink).
// Including a standard header first gives every file the same configuration.
#pragma once

#include <cstddef>
// (a blank line keeps clang-format from sorting Asio above <cstddef>)

#include <asio.hpp>
