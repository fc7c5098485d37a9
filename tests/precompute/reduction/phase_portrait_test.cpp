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
  const std::vector<std::int32_t> length(start.size(), N / n_irf);
  const MatrixXiR cache = nearest_irf_cache(q, v, beta, start, length, palette, D);
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

// The brute force the cache must equal: eq. 9 with each difference in
// double; of the starts within kSameStartFraction of the portrait's radius
// of the nearest, the longest IRF, then the nearest, then the lowest index.
int brute_force_choice(const MatrixXfR& q, const MatrixXfR& v, double beta,
                       const std::vector<std::int32_t>& start, const std::vector<std::int32_t>& length,
                       const std::vector<std::int32_t>& palette, int node, int d,
                       const std::vector<SupportVelocity>& support = {}) {
  // Only starts that moved the support as node does, unless none of entry d did.
  std::vector<char> candidate(start.size(), 0);
  bool any_at_velocity = false;
  for (size_t i = 0; i < start.size(); ++i) {
    candidate[i] = palette[i] == d && (support.empty() || support[start[i]] == support[node]);
    any_at_velocity = any_at_velocity || candidate[i];
  }
  for (size_t i = 0; i < start.size() && !any_at_velocity; ++i) candidate[i] = palette[i] == d;
  double radius = 0;
  for (Eigen::Index i = 0; i < q.rows(); ++i)
    radius = std::max(radius, std::sqrt(q.row(i).cast<double>().squaredNorm() +
                                        beta * v.row(i).cast<double>().squaredNorm()));
  const auto distance = [&](size_t i) {
    return std::sqrt((q.row(node).cast<double>() - q.row(start[i]).cast<double>()).squaredNorm() +
                     beta * (v.row(node).cast<double>() - v.row(start[i]).cast<double>()).squaredNorm());
  };
  double nearest = INFINITY;
  for (size_t i = 0; i < start.size(); ++i)
    if (candidate[i]) nearest = std::min(nearest, distance(i));
  int best = -1;
  for (size_t i = 0; i < start.size(); ++i) {
    if (!candidate[i] || distance(i) > nearest + kSameStartFraction * radius) continue;
    const auto b = static_cast<size_t>(best);
    if (best < 0 || length[i] > length[b] || (length[i] == length[b] && distance(i) < distance(b)))
      best = static_cast<int>(i);
  }
  return best;
}

// Many starts near one rest state far from the origin (|b|^2 large, the
// differences tiny): float32 |b|^2 - 2 a.b would pick wrong ones here.
TEST(IrfCache, NearDuplicateStartsAtRestAreToldApartExactly) {
  std::mt19937 rng(11);
  std::normal_distribution<float> jitter(0.0f, 1e-4f);
  const int N = 2000, r = 12, D = 2, n_irf = 400;
  MatrixXfR q(N, r), v(N, r);
  for (int i = 0; i < N; ++i) {
    for (int c = 0; c < r; ++c) {
      q(i, c) = 30.0f + static_cast<float>(c) + jitter(rng);  // the rest state, far out
      v(i, c) = jitter(rng);
    }
  }
  std::vector<std::int32_t> start, palette;
  for (int i = 0; i < n_irf; ++i) {
    start.push_back(i * (N / n_irf));
    palette.push_back(i % D);
  }
  std::vector<std::int32_t> length(start.size(), 5);
  // Every start lies within 1 % of the radius of every other here: for entry 1,
  // whose IRF 7 is the longest, it plays from everywhere; entry 0's IRFs are
  // equally long, so its choice is the exact nearest (the brute force checks it).
  start[7] = start[5];
  length[7] = 6;
  start[10] = start[8];  // two of entry 0 at one node: the first sampled
  const double beta = 2.5;
  const MatrixXiR cache = nearest_irf_cache(q, v, beta, start, length, palette, D);
  int checked = 0;
  for (int j = 0; j < N; ++j) {
    for (int d = 0; d < D; ++d) {
      ASSERT_EQ(cache(j, d), brute_force_choice(q, v, beta, start, length, palette, j, d))
          << "node " << j << " entry " << d;
      ++checked;
    }
  }
  EXPECT_EQ(checked, N * D);
  EXPECT_EQ(cache(start[5], 1), 7);  // not 5, at the same distance 0 but shorter
  EXPECT_EQ(cache(start[9], 1), 7);  // the longest within the band, not the nearest
  EXPECT_EQ(cache(start[8], 0), 8);  // not 10: as long, as near, sampled later
  // Not vacuous: the float32 score |b|^2 - 2 a.b misorders these starts.
  int float_misses = 0;
  for (int j = 0; j < N; ++j) {
    float least = INFINITY;
    int pick = -1;
    for (int i = 0; i < n_irf; i += D) {
      const float score =
          q.row(start[i]).squaredNorm() + beta * v.row(start[i]).squaredNorm() -
          2 * (q.row(j).dot(q.row(start[i])) + static_cast<float>(beta) * v.row(j).dot(v.row(start[i])));
      if (score < least) least = score, pick = i;
    }
    float_misses += pick != cache(j, 0);
  }
  EXPECT_GT(float_misses, N / 10);
}

// The support's velocity at each node: its IRF's entry's, and at its first node
// the velocity of the IRF it continues (0 from rest).
TEST(SupportVelocities, FirstNodesKeepTheVelocityTheImpulseFinds) {
  const std::vector<SupportVelocity> held = {{-0.5, 0, 0}, {0.5, 0, 0}, {0, 0, 0}};  // left, right, stop
  const auto v = support_velocities({0, 3, 5, 7}, {3, 2, 2, 2}, {0, 2, 1, 2}, {0, 1, 0, 1}, held);
  const std::vector<SupportVelocity> want = {{0, 0, 0}, {-0.5, 0, 0}, {-0.5, 0, 0}, {-0.5, 0, 0}, {0, 0, 0},
                                             {0, 0, 0}, {0.5, 0, 0},  {0.5, 0, 0},  {0, 0, 0}};
  EXPECT_EQ(v, want);
  EXPECT_THROW(support_velocities({0}, {2}, {3}, {0}, held),
               std::invalid_argument);  // entry without a velocity
  EXPECT_THROW(support_velocities({0, 3}, {2, 2}, {0, 0}, {0, 0}, held), std::invalid_argument);  // a gap
}

// A stop after a push left is the opposite kick of a stop after a push right:
// from a node of a push left, the stop that started after one plays, though a
// stop that started after a push right lies nearer under eq. 9.
TEST(IrfCache, AnImpulsePlaysAnIrfThatStartedAtTheSameSupportVelocity) {
  // IRFs: left (nodes 0-2), stop after it (3-5), right (6-8), stop after it (9-11).
  MatrixXfR q(12, 1), v = MatrixXfR::Zero(12, 1);
  q << 0, 1, 2, 2.6f, 1.5f, 0, 0, -1, -2, 2.1f, 1, 0;
  const std::vector<std::int32_t> start = {0, 3, 6, 9}, length = {3, 3, 3, 3}, palette = {0, 2, 1, 2};
  const std::vector<SupportVelocity> held = {{-0.5, 0, 0}, {0.5, 0, 0}, {0, 0, 0}};
  const auto support = support_velocities(start, length, palette, {0, 1, 0, 1}, held);
  const MatrixXiR cache = nearest_irf_cache(q, v, 1.0, start, length, palette, 3, support);
  EXPECT_EQ(cache(2, 2), 1);  // at q = 2 moving left: the stop from 2.6 after a left, not the one from 2.1
  EXPECT_EQ(cache(8, 2), 3);  // moving right: the only stop after a right
  EXPECT_EQ(nearest_irf_cache(q, v, 1.0, start, length, palette, 3)(2, 2),
            3);  // eq. 9 alone: the nearer start
  // No stop started still: from a still node, the nearest of all.
  EXPECT_EQ(cache(5, 2), 3);
  EXPECT_EQ(cache(5, 0), 0);  // a push from a still node: the one push left, which started still
  EXPECT_THROW(nearest_irf_cache(q, v, 1.0, start, length, palette, 3, {{0, 0, 0}}), std::invalid_argument);
}

// The same against the brute force: random states, three entries, chains of
// random entries.
TEST(IrfCache, MatchesBruteForceWithSupportVelocities) {
  std::mt19937 rng(5);
  std::normal_distribution<float> n;
  const int r = 4, D = 3, n_irf = 90, len = 20, N = n_irf * len;
  MatrixXfR q(N, r), v(N, r);
  for (int i = 0; i < q.size(); ++i) q.data()[i] = n(rng), v.data()[i] = n(rng);
  std::vector<std::int32_t> start, length(n_irf, len), palette;
  std::vector<std::uint8_t> continues;
  for (int i = 0; i < n_irf; ++i) {
    start.push_back(i * len);
    palette.push_back(static_cast<std::int32_t>(rng() % D));
    continues.push_back(i > 0 && rng() % 4 != 0);
  }
  const std::vector<SupportVelocity> held = {{-0.5, 0, 0}, {0.5, 0, 0}, {0, 0, 0}};
  const auto support = support_velocities(start, length, palette, continues, held);
  const MatrixXiR cache = nearest_irf_cache(q, v, 0.7, start, length, palette, D, support);
  int moved = 0;
  const MatrixXiR plain = nearest_irf_cache(q, v, 0.7, start, length, palette, D);
  for (int j = 0; j < N; j += 3) {
    for (int d = 0; d < D; ++d) {
      ASSERT_EQ(cache(j, d), brute_force_choice(q, v, 0.7, start, length, palette, j, d, support))
          << "node " << j << " entry " << d;
      moved += cache(j, d) != plain(j, d);
    }
  }
  EXPECT_GT(moved, N / 10);  // not vacuous: the velocity changes many choices
}

// Starts within 1 % of the portrait's radius of the nearest are one state:
// the longest IRF among them plays (a later impulse can cut it short).
TEST(IrfCache, TheLongestIrfOfOneStartPlays) {
  MatrixXfR q(4, 1), v = MatrixXfR::Zero(4, 1);
  q << 0, 0.05f, 0.2f, 10;  // radius 10: starts within 0.1 of the nearest count as one
  const MatrixXiR cache = nearest_irf_cache(q, v, 1.0, {0, 1, 2, 3}, {3, 9, 20, 1}, {0, 0, 0, 0}, 1);
  EXPECT_EQ(cache(0, 0), 1);  // 0.05 away and three times as long; 0.2 is another state
  EXPECT_EQ(cache(1, 0), 1);
  EXPECT_EQ(cache(2, 0), 2);  // the nearest (itself) and the longest
  EXPECT_EQ(cache(3, 0), 3);
}

TEST(IrfCache, AnIrfStartMapsToItself) {
  MatrixXfR q(6, 1), v = MatrixXfR::Zero(6, 1);
  q << 0, 1, 2, 5, 6, 7;
  const MatrixXiR cache = nearest_irf_cache(q, v, 1.0, {0, 3}, {3, 3}, {0, 0}, 1);
  EXPECT_EQ(cache(0, 0), 0);
  EXPECT_EQ(cache(3, 0), 1);
  EXPECT_EQ(cache(2, 0), 0);  // |2 - 0| < |2 - 5|
  EXPECT_EQ(cache(4, 0), 1);
}

}  // namespace
}  // namespace phasecast::precompute
