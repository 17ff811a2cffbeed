// The error contract of the readers: one FormatError line "<file>: <what is wrong>".
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <voxwall/core/errors.hpp>

namespace voxwall::test {

// Expects f() to throw FormatError whose message starts with "<file>: ", is one line, and holds
// `fragment` (when not empty).
template <class F>
void expectFormatError(F&& f, const std::string& file, const std::string& fragment = "") {
  try {
    f();
    ADD_FAILURE() << "no error for " << file;
  } catch (const FormatError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(file + ": ", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    if (!fragment.empty()) {
      EXPECT_NE(what.find(fragment), std::string::npos) << what;
    }
  }
}

}  // namespace voxwall::test
