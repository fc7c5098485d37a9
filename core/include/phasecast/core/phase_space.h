#pragma once
// Eq. 9 of the paper, the one distance between phase-space points (q, q̇):
//   D(a, b)^2 = ||q_a - q_b||^2 + beta ||q̇_a - q̇_b||^2,
// beta weighting velocity against displacement (§2.3.2). The sampler's
// dead-end filter, the IRF reference cache and the server's rest node all
// measure with it.

#include "phasecast/core/eigen_types.h"

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <vector>

namespace phasecast::core {

// Two states within this fraction of the portrait's radius (the largest
// sqrt(||q||^2 + beta ||q̇||^2) of its nodes) count as one under eq. 9: of such
// near-equal candidates the IRF cache and the server's orbit extension take
// the one with the most frames left to play.
inline constexpr double kSameStateFraction = 0.01;

template <class QA, class VA, class QB, class VB>
double phase_distance_squared(const Eigen::MatrixBase<QA>& q_a, const Eigen::MatrixBase<VA>& qdot_a,
                              const Eigen::MatrixBase<QB>& q_b, const Eigen::MatrixBase<VB>& qdot_b,
                              double beta) {
  return (q_a - q_b).template cast<double>().squaredNorm() +
         beta * (qdot_a - qdot_b).template cast<double>().squaredNorm();
}

// Rows [q, sqrt(beta) q̇]: the Euclidean distance between two rows is eq. 9,
// so bulk nearest-neighbour searches can use matrix products.
inline Eigen::MatrixXf phase_points(const MatrixXfR& q, const MatrixXfR& qdot, double beta) {
  Eigen::MatrixXf x(q.rows(), 2 * q.cols());
  x.leftCols(q.cols()) = q;
  x.rightCols(q.cols()) = qdot * static_cast<float>(std::sqrt(beta));
  return x;
}

// Eq. 8: the velocity of every state node of a set of orbits (one row per
// node, IRFs tiling the rows), by first-order differences in the paper's
// convention: forward differences (x^{k+1} - x^k) / dt along an IRF, and the
// one-sided backward difference (x^k - x^{k-1}) / dt "for the orbit's final
// state, and prior to IRF discontinuities". The discontinuity of an IRF lies
// between its first node (the state the impulse finds) and its second, so its
// first node gets the velocity it arrived with: the backward difference from
// the previous IRF when it continues that IRF's motion (`irf_continues`), zero
// when it starts from the settled rest. This is the state the run-time lookup
// (§5.2) compares with, the velocity before the impulse.
MatrixXfR orbit_velocities(const MatrixXfR& x, const std::vector<std::int32_t>& irf_start,
                           const std::vector<std::int32_t>& irf_length,
                           const std::vector<std::uint8_t>& irf_continues, double dt);

}  // namespace phasecast::core
