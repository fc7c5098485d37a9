#include "phasecast/client/frame_state.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace phasecast::client {
namespace {

void expect_finite(const std::vector<float>& v, const char* what, const FrameState& f,
                   const std::string& source) {
  const auto bad = std::find_if(v.begin(), v.end(), [](float x) { return !std::isfinite(x); });
  if (bad != v.end()) {
    throw std::invalid_argument(fmt::format("{}: frame {}: {}[{}] is {} (expected a finite number)", source,
                                            f.frame, what, bad - v.begin(), *bad));
  }
}

}  // namespace

void validate_frame(const FrameState& f, const ClientBasis& b, const std::string& source) {
  if (f.q_u.size() != static_cast<std::size_t>(b.rank_u)) {
    throw std::invalid_argument(fmt::format("{}: frame {}: q_u has {} values (expected r_u = {})", source,
                                            f.frame, f.q_u.size(), b.rank_u));
  }
  if (f.q_a.size() != static_cast<std::size_t>(b.rank_a)) {
    throw std::invalid_argument(fmt::format("{}: frame {}: q_a has {} values (expected r_a = {})", source,
                                            f.frame, f.q_a.size(), b.rank_a));
  }
  if (!f.support.empty() && f.support.size() != 12) {
    throw std::invalid_argument(
        fmt::format("{}: frame {}: support has {} values (expected 12, a 3x4 row-major transform)", source,
                    f.frame, f.support.size()));
  }
  expect_finite(f.q_u, "q_u", f, source);
  expect_finite(f.q_a, "q_a", f, source);
  expect_finite(f.support, "support", f, source);
}

}  // namespace phasecast::client
