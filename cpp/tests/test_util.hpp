// Helpers shared by the GoogleTest files.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <utility>

namespace nbv_test {

/// The message of the std::invalid_argument that f(args...) throws, or "" when it returns (any
/// other exception escapes, failing the test).
template <class F, class... Args>
std::string error_of(F&& f, Args&&... args) {
  try {
    std::invoke(std::forward<F>(f), std::forward<Args>(args)...);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace nbv_test
