#pragma once
// The one-line message a user would see: what `f` throws as E, or "(no error)"
// when it throws nothing (so a missing error fails the comparison visibly).

#include <exception>
#include <string>
#include <utility>

namespace phasecast::testing {

template <class E = std::exception, class F>
std::string error_of(F&& f) {
  try {
    std::forward<F>(f)();
  } catch (const E& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace phasecast::testing
