// The affine-knn interpolant of q_a over q_u against closed forms: an affine
// function is carried exactly between samples, every sample is reproduced at
// its centre, and leave-one-out refits the map without the sample it predicts.

#include "phasecast/precompute/appearance/interpolant.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace phasecast {
namespace {

using namespace precompute;

MatrixXfR random_points(Eigen::Index n, Eigen::Index dims, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  MatrixXfR q(n, dims);
  for (Eigen::Index i = 0; i < q.size(); ++i)
    q.data()[i] = static_cast<float>(static_cast<double>(rng() >> 11) * 0x1.0p-53 * 2 - 1);
  return q;
}

// q_a = a + q B: 3 outputs of a 4-dimensional q_u.
MatrixXfR affine_of(const MatrixXfR& q) {
  Eigen::MatrixXf B(4, 3);
  B << 1, -2, 0.5f, 0, 3, 1, -1, 0, 2, 0.25f, 1, -3;
  MatrixXfR out = q * B;
  out.rowwise() += Eigen::RowVector3f(0.5f, -1, 2);
  return out;
}

TEST(AffineKnn, CarriesAnAffineFunctionExactlyBetweenSamples) {
  const MatrixXfR centers = random_points(20, 4, 1), queries = random_points(50, 4, 2);
  const Interpolant f = tune_affine_knn(centers, affine_of(centers));
  EXPECT_EQ(f.kind, InterpolantKind::affine_knn);
  EXPECT_LT(f.leave_one_out, 1e-5);
  const MatrixXfR want = affine_of(queries);
  EXPECT_LT((evaluate_interpolant(f, queries) - want).norm(), 1e-4f * want.norm());
  // knn alone cannot: it averages neighbours, and an affine function is not flat.
  const Interpolant knn = tune_knn(centers, affine_of(centers));
  EXPECT_GT((evaluate_interpolant(knn, queries) - want).norm(), 0.1f * want.norm());
  EXPECT_GT(knn.leave_one_out, 0.1);
}

TEST(AffineKnn, ReproducesEverySampleAndBeatsKnnOnANearlyAffineFunction) {
  const MatrixXfR centers = random_points(40, 4, 3), queries = random_points(200, 4, 4);
  const auto curved = [](const MatrixXfR& q) {  // affine plus a small bump
    MatrixXfR out = affine_of(q);
    for (Eigen::Index i = 0; i < q.rows(); ++i) out(i, 0) += 0.3f * std::sin(3 * q(i, 0)) * q(i, 1);
    return out;
  };
  const MatrixXfR samples = curved(centers);
  const Interpolant f = tune_affine_knn(centers, samples);
  EXPECT_LT((evaluate_interpolant(f, centers) - samples).norm(), 1e-5f * samples.norm());
  const MatrixXfR want = curved(queries);
  const float affine_error = (evaluate_interpolant(f, queries) - want).norm() / want.norm();
  const float knn_error =
      (evaluate_interpolant(tune_knn(centers, samples), queries) - want).norm() / want.norm();
  EXPECT_GT(affine_error, 1e-4f) << "not vacuous: the bump is not affine";
  EXPECT_LT(affine_error, 0.5f * knn_error) << affine_error << " vs knn " << knn_error;
  EXPECT_GT(f.leave_one_out, 0);
  EXPECT_LT(f.leave_one_out, tune_knn(centers, samples).leave_one_out);
}

// Leave-one-out refits the map without the left-out sample: with 1 + r_u
// samples the map through all of them is exact, yet each left-out sample is
// predicted by a least-norm map of the others, so the error is not zero.
TEST(AffineKnn, LeaveOneOutRefitsTheMapWithoutTheSample) {
  const MatrixXfR centers = random_points(5, 4, 5);
  MatrixXfR samples = random_points(5, 3, 6);
  const Interpolant f = tune_affine_knn(centers, samples);
  EXPECT_LT((evaluate_interpolant(f, centers) - samples).norm(), 1e-4f * samples.norm());
  EXPECT_LT(f.nrbf.weights.norm(), 1e-4f * samples.norm()) << "the map fits 5 samples in 5 unknowns";
  EXPECT_GT(f.leave_one_out, 0.05);
  // Fewer samples than unknowns: the least-norm map still passes through them.
  const Interpolant few = tune_affine_knn(centers.topRows(3), samples.topRows(3));
  EXPECT_LT((evaluate_interpolant(few, centers.topRows(3)) - samples.topRows(3)).norm(),
            1e-4f * samples.topRows(3).norm());
  // One sample: a constant (the slope is left open, and the least-norm one is 0).
  const Interpolant one = tune_affine_knn(centers.topRows(1), samples.topRows(1));
  EXPECT_EQ(one.leave_one_out, 0);
  EXPECT_LT((evaluate_interpolant(one, centers.bottomRows(1)) - samples.topRows(1)).norm(), 1e-5f);
}

TEST(AffineKnnRejects, MismatchedInput) {
  const MatrixXfR centers = random_points(5, 4, 7);
  try {
    tune_affine_knn(centers, random_points(4, 3, 8));
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "affine-knn: expected one sample per centre (5), got 4");
  }
  const Interpolant f = tune_affine_knn(centers, random_points(5, 3, 8));
  EXPECT_THROW(evaluate_interpolant(f, random_points(2, 3, 9)), std::invalid_argument);
}

}  // namespace
}  // namespace phasecast
