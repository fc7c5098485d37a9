#pragma once
// Seconds since construction, for the stages' timing lines.

#include <chrono>

namespace phasecast::precompute {

class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

}  // namespace phasecast::precompute
