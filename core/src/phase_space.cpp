#include "phasecast/core/phase_space.h"

#include <stdexcept>
#include <string>

namespace phasecast::core {
namespace {

void check_layout(const MatrixXfR& x, const std::vector<std::int32_t>& start,
                  const std::vector<std::int32_t>& length, const std::vector<std::uint8_t>& continues,
                  double dt) {
  if (!(dt > 0)) throw std::invalid_argument("orbit velocities: dt must be positive");
  if (start.size() != length.size() || start.size() != continues.size()) {
    throw std::invalid_argument("orbit velocities: IRF starts, lengths and continues differ in count");
  }
  for (size_t i = 0; i < start.size(); ++i) {
    if (start[i] < 0 || length[i] < 1 || start[i] + length[i] > x.rows() || (continues[i] && start[i] == 0)) {
      throw std::invalid_argument("orbit velocities: IRF " + std::to_string(i) + " lies outside the nodes" +
                                  (continues[i] && start[i] == 0 ? " (continues from before node 0)" : ""));
    }
  }
}

}  // namespace

MatrixXfR orbit_velocities(const MatrixXfR& x, const std::vector<std::int32_t>& start,
                           const std::vector<std::int32_t>& length,
                           const std::vector<std::uint8_t>& continues, double dt) {
  check_layout(x, start, length, continues, dt);
  const auto inv_dt = static_cast<float>(1.0 / dt);
  MatrixXfR v = MatrixXfR::Zero(x.rows(), x.cols());
  for (size_t i = 0; i < start.size(); ++i) {
    const Eigen::Index s = start[i], e = s + length[i] - 1;
    if (continues[i]) v.row(s) = (x.row(s) - x.row(s - 1)) * inv_dt;  // the velocity the impulse finds
    if (e > s + 1)
      v.middleRows(s + 1, e - s - 1) =
          (x.middleRows(s + 2, e - s - 1) - x.middleRows(s + 1, e - s - 1)) * inv_dt;
    if (e == s) continue;
    const bool next_continues = i + 1 < start.size() && continues[i + 1];
    v.row(e) = next_continues ? (x.row(e + 1) - x.row(e)) * inv_dt : (x.row(e) - x.row(e - 1)) * inv_dt;
  }
  return v;
}

}  // namespace phasecast::core
