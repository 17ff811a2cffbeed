// Exceptions for data and environment problems (docs/architecture.md, "Conventions").
#pragma once

#include <stdexcept>
#include <string>

namespace voxwall {

// A file or stream whose contents are wrong: truncated, corrupt, unsupported.
// `what()` is "<file>: <what is wrong>" so the program can print it as it is.
class FormatError : public std::runtime_error {
 public:
  FormatError(const std::string& file, const std::string& what)
      : std::runtime_error(file.empty() ? what : file + ": " + what), file_(file) {}
  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

}  // namespace voxwall
