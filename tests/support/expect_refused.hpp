// Settings refused with the option's name: expects std::invalid_argument from `f` whose message
// starts with `prefix`.
#pragma once

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace voxwall::test {

template <class F>
void expectRefused(F&& f, const std::string& prefix) {
  try {
    f();
    ADD_FAILURE() << "accepted; expected: " << prefix;
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
  }
}

}  // namespace voxwall::test
