// Eq. 8 velocities at IRF starts and ends, the beta default, and the IRF cache (§5.2)
// against a brute-force search.

#include "phasecast/precompute/reduction/phase_portrait.h"
#include "phasecast/core/phase_space.h"

#include <gtest/gtest.h>

#include <random>

namespace phasecast::precompute {
namespace {

// Eq. 8 with the impulse between an IRF's first and second node: the first
// node keeps the velocity the impulse finds (the backward difference from the
// IRF it continues), never the jump the impulse causes.
TEST(OrbitVelocities, IrfStartsKeepThePreImpulseVelocity) {
  MatrixXfR q(6, 1);
  // IRF 0: nodes 0..2 from rest; IRF 1 continues it at node 3, where an
  // impulse turns a motion of +1 per node into +10 per node.
  q << 0, 1, 2, 3, 13, 23;
  const MatrixXfR v = core::orbit_velocities(q, {0, 3}, {3, 3}, {0, 1}, 0.5);
  EXPECT_FLOAT_EQ(v(0, 0), 0);   // starts from the settled rest
  EXPECT_FLOAT_EQ(v(1, 0), 2);   // (2 - 1) / 0.5
  EXPECT_FLOAT_EQ(v(2, 0), 2);   // (3 - 2) / 0.5: node 3 continues the motion, no switch yet
  EXPECT_FLOAT_EQ(v(3, 0), 2);   // (3 - 2) / 0.5: the state before the impulse, not (13 - 3) / 0.5
  EXPECT_FLOAT_EQ(v(4, 0), 20);  // (23 - 13) / 0.5
  EXPECT_FLOAT_EQ(v(5, 0), 20);  // orbit end: backward
}

TEST(OrbitVelocities, AnIrfFromRestStartsStillAndItsPredecessorEndsBackward) {
  MatrixXfR q(5, 1);
  q << 0, 1, 3, 50, 51;  // IRF 1 (nodes 3..4) restarts from rest: node 3 is not after node 2
  const MatrixXfR v = core::orbit_velocities(q, {0, 3}, {3, 2}, {0, 0}, 1.0);
  EXPECT_FLOAT_EQ(v(2, 0), 2);  // backward: never across to an unrelated orbit
  EXPECT_FLOAT_EQ(v(3, 0), 0);
  EXPECT_FLOAT_EQ(v(4, 0), 1);
}

TEST(OrbitVelocities, SingleNodeIrfFromRestHasZeroVelocity) {
  MatrixXfR q(1, 2);
  q << 1, 2;
  EXPECT_TRUE(core::orbit_velocities(q, {0}, {1}, {0}, 0.1).isZero());
}

TEST(OrbitVelocities, RejectsBadInput) {
  MatrixXfR q = MatrixXfR::Zero(3, 1);
  EXPECT_THROW(core::orbit_velocities(q, {0}, {4}, {0}, 0.1), std::invalid_argument);
  EXPECT_THROW(core::orbit_velocities(q, {0}, {3}, {0}, 0.0), std::invalid_argument);
  EXPECT_THROW(core::orbit_velocities(q, {0, 1}, {3}, {0}, 0.1), std::invalid_argument);
  EXPECT_THROW(core::orbit_velocities(q, {0}, {3}, {1}, 0.1),
               std::invalid_argument);  // nothing before node 0
}

TEST(DefaultBeta, BalancesPositionAndVelocityRanges) {
  MatrixXfR q(2, 2), v(2, 2);
  q << 3, 4, 1, 0;   // max |q|^2 = 25
  v << 0, 1, 0, 10;  // max |v|^2 = 100
  EXPECT_DOUBLE_EQ(default_beta(q, v), 0.25);
  EXPECT_DOUBLE_EQ(default_beta(q, MatrixXfR::Zero(2, 2)), 1.0);
}

TEST(IrfCache, MatchesBruteForceEq9) {
  std::mt19937 rng(3);
  std::normal_distribution<float> n;
  const int N = 3000, r = 5, D = 4, n_irf = 60;
  MatrixXfR q(N, r), v(N, r);
  for (int i = 0; i < q.size(); ++i) q.data()[i] = n(rng), v.data()[i] = n(rng);
  std::vector<std::int32_t> start, palette;
  for (int i = 0; i < n_irf; ++i) {
    start.push_back(i * (N / n_irf));
    palette.push_back(i % (D - 1));  // entry D-1 has no IRF
  }
  const double beta = 0.3;
  const MatrixXiR cache = nearest_irf_cache(q, v, beta, start, palette, D);
  ASSERT_EQ(cache.rows(), N);
  ASSERT_EQ(cache.cols(), D);
  for (int j = 0; j < N; j += 7) {
    for (int d = 0; d < D; ++d) {
      int best = -1;
      double best_dist = INFINITY;
      for (int i = 0; i < n_irf; ++i) {
        if (palette[static_cast<size_t>(i)] != d) continue;
        const int s = start[static_cast<size_t>(i)];
        const double dist = (q.row(j) - q.row(s)).cast<double>().squaredNorm() +
                            beta * (v.row(j) - v.row(s)).cast<double>().squaredNorm();
        if (dist < best_dist) best_dist = dist, best = i;
      }
      EXPECT_EQ(cache(j, d), best) << "node " << j << " entry " << d;
    }
  }
}

TEST(IrfCache, AnIrfStartMapsToItself) {
  MatrixXfR q(6, 1), v = MatrixXfR::Zero(6, 1);
  q << 0, 1, 2, 5, 6, 7;
  const MatrixXiR cache = nearest_irf_cache(q, v, 1.0, {0, 3}, {0, 0}, 1);
  EXPECT_EQ(cache(0, 0), 0);
  EXPECT_EQ(cache(3, 0), 1);
  EXPECT_EQ(cache(2, 0), 0);  // |2 - 0| < |2 - 5|
  EXPECT_EQ(cache(4, 0), 1);
}

}  // namespace
}  // namespace phasecast::precompute
