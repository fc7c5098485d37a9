// Regularized normalized RBF interpolation (§4.3) on functions with known values.

#include "phasecast/precompute/appearance/nrbf.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <random>

namespace phasecast {
namespace {

using precompute::evaluate_nrbf;
using precompute::fit_nrbf;
using precompute::nrbf_leave_one_out;

MatrixXfR random_matrix(Eigen::Index rows, Eigen::Index cols, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  MatrixXfR M(rows, cols);
  for (Eigen::Index i = 0; i < M.size(); ++i) {
    M.data()[i] = static_cast<float>(static_cast<double>(rng() >> 11) * 0x1.0p-53 * 2 - 1);
  }
  return M;
}

// 1-D samples of sin(x) at x = 0, h, ..., 2 pi.
struct Sine {
  MatrixXfR x, y;
  VectorXf widths;
  explicit Sine(int count) : x(count, 1), y(count, 1), widths(VectorXf::Constant(count, 0.0f)) {
    const float h = static_cast<float>(2 * M_PI / (count - 1));
    for (int i = 0; i < count; ++i) {
      x(i, 0) = h * static_cast<float>(i);
      y(i, 0) = std::sin(x(i, 0));
    }
    widths.setConstant(h);
  }
};

TEST(Nrbf, WithoutRegularizationInterpolatesTheSamples) {
  const MatrixXfR C = random_matrix(12, 3, 1) * 2;
  const MatrixXfR V = random_matrix(12, 4, 2);
  const auto f = fit_nrbf(C, VectorXf::Constant(12, 0.7f), V, 0.0f);
  EXPECT_LT((evaluate_nrbf(f, C) - V).cwiseAbs().maxCoeff(), 1e-4f);
}

TEST(Nrbf, ReproducesAConstantEverywhere) {
  const MatrixXfR C = random_matrix(10, 2, 3);
  const MatrixXfR V = MatrixXfR::Constant(10, 2, 0.375f);
  const auto f = fit_nrbf(C, VectorXf::Constant(10, 0.5f), V, 0.0f);
  const MatrixXfR q = random_matrix(50, 2, 4) * 3;
  EXPECT_LT((evaluate_nrbf(f, q).array() - 0.375f).abs().maxCoeff(), 1e-5f);  // partition of unity
}

TEST(Nrbf, InterpolatesASmoothFunctionBetweenSamples) {
  const Sine s(33);
  const auto f = fit_nrbf(s.x, s.widths, s.y, 1e-6f);
  MatrixXfR mid(32, 1);
  for (int i = 0; i < 32; ++i) mid(i, 0) = (s.x(i, 0) + s.x(i + 1, 0)) / 2;
  const MatrixXfR got = evaluate_nrbf(f, mid);
  for (int i = 0; i < 32; ++i) EXPECT_NEAR(got(i, 0), std::sin(mid(i, 0)), 0.01) << "x = " << mid(i, 0);
}

TEST(Nrbf, FarFromAllCentresTendsToTheNearestWeight) {
  const Sine s(9);
  const auto f = fit_nrbf(s.x, s.widths, s.y, 1e-3f);
  MatrixXfR q(2, 1);
  q << 1e4f, -1e4f;
  const MatrixXfR got = evaluate_nrbf(f, q);
  EXPECT_FLOAT_EQ(got(0, 0), f.weights(8, 0));
  EXPECT_FLOAT_EQ(got(1, 0), f.weights(0, 0));
}

TEST(Nrbf, RegularizationTradesExactnessForSmoothness) {
  const MatrixXfR C = random_matrix(15, 2, 5);
  const MatrixXfR V = random_matrix(15, 1, 6);
  const VectorXf w = VectorXf::Constant(15, 0.4f);
  double previous = -1;
  for (const float lambda : {0.0f, 1e-3f, 1e-1f, 10.0f}) {
    const double residual = (evaluate_nrbf(fit_nrbf(C, w, V, lambda), C) - V).norm();
    EXPECT_GT(residual, previous) << "lambda " << lambda;
    previous = residual;
  }
}

TEST(Nrbf, LeaveOneOutSeparatesSmoothDataFromNoise) {
  const Sine s(33);
  const auto smooth = nrbf_leave_one_out(s.x, s.widths, s.y, 1e-6f);
  EXPECT_EQ(smooth.errors.size(), 33);
  EXPECT_LT(smooth.relative, 0.05);
  const MatrixXfR noise = random_matrix(33, 1, 7);
  EXPECT_GT(nrbf_leave_one_out(s.x, s.widths, noise, 1e-6f).relative, 0.5);
  // A constant is predicted exactly from the others.
  const auto constant = nrbf_leave_one_out(s.x, s.widths, MatrixXfR::Constant(33, 1, 2.0f), 0.0f);
  EXPECT_LT(constant.rms, 1e-5);
  EXPECT_NEAR(constant.rms * std::sqrt(33.0), constant.errors.cast<double>().norm(), 1e-9);
}

// The N_a refits run side by side: each must be the refit a plain loop makes,
// whatever the number of threads, so that packages stay bit-identical.
TEST(Nrbf, LeaveOneOutIsEachRefitOnAnyNumberOfThreads) {
  const MatrixXfR C = random_matrix(40, 3, 21), V = random_matrix(40, 2, 22);
  const VectorXf w = VectorXf::Constant(40, 0.6f);
  VectorXf by_hand(40);
  double err2 = 0, norm2 = 0;
  for (Eigen::Index j = 0; j < 40; ++j) {
    MatrixXfR Cj(39, 3), Vj(39, 2);
    for (Eigen::Index i = 0, k = 0; i < 40; ++i) {
      if (i == j) continue;
      Cj.row(k) = C.row(i);
      Vj.row(k++) = V.row(i);
    }
    const double e =
        (evaluate_nrbf(fit_nrbf(Cj, w.head(39), Vj, 1e-4f), C.row(j)) - V.row(j)).cast<double>().norm();
    by_hand[j] = static_cast<float>(e);
    err2 += e * e;
    norm2 += V.row(j).cast<double>().squaredNorm();
  }
  const auto threaded = nrbf_leave_one_out(C, w, V, 1e-4f);
  const auto one = [&] {
    const tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
    return nrbf_leave_one_out(C, w, V, 1e-4f);
  }();
  for (const auto& r : {threaded, one}) {
    EXPECT_TRUE(r.errors == by_hand);
    EXPECT_EQ(r.rms, std::sqrt(err2 / 40));
    EXPECT_EQ(r.relative, std::sqrt(err2 / norm2));
  }
}

TEST(Nrbf, WidthsFromClusterSpread) {
  MatrixXfR q(6, 2);
  q << 0, 0, 1, 0, -1, 0,  // cluster 0 around (0, 0): RMS distance sqrt(2/3)
      10, 0,               // cluster 1: a single node
      0, 4, 0, 4;          // cluster 2: two identical nodes
  const std::vector<std::int32_t> labels{0, 0, 0, 1, 2, 2};
  MatrixXfR centers(3, 2);
  centers << 0, 0, 10, 0, 0, 4;
  const VectorXf w = precompute::nrbf_widths(q, labels, centers);
  EXPECT_FLOAT_EQ(w[0], std::sqrt(2.0f / 3.0f));
  EXPECT_FLOAT_EQ(w[1], 5.0f);  // half the distance to the nearest centre (0, 0)
  EXPECT_FLOAT_EQ(w[2], 2.0f);  // half of |(0, 4) - (0, 0)|
  EXPECT_FLOAT_EQ(precompute::nrbf_widths(q, labels, centers, 2.0f)[0], 2 * std::sqrt(2.0f / 3.0f));
  EXPECT_FLOAT_EQ(precompute::nrbf_widths(q.topRows(1), {0}, centers.topRows(1))[0], 1.0f);
}

template <class F>
std::string failure_of(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}

TEST(NrbfRejects, BadInput) {
  const MatrixXfR C = random_matrix(4, 2, 8), V = random_matrix(4, 3, 9);
  const VectorXf w = VectorXf::Ones(4);
  VectorXf bad_w = w;
  bad_w[2] = 0;
  EXPECT_EQ(failure_of([&] { fit_nrbf(C, bad_w, V); }), "nrbf: width 2 must be positive and finite, got 0");
  EXPECT_EQ(failure_of([&] { fit_nrbf(C, VectorXf::Ones(3), V); }),
            "nrbf: expected 4 widths (one per centre), got 3");
  EXPECT_EQ(failure_of([&] { fit_nrbf(C, w, V.topRows(2)); }),
            "nrbf: values must have 4 rows (one per centre), got 2");
  EXPECT_EQ(failure_of([&] { fit_nrbf(C, w, V, -1.0f); }),
            "nrbf: regularization must be finite and >= 0, got -1");
  MatrixXfR nan_v = V;
  nan_v(0, 0) = NAN;
  EXPECT_EQ(failure_of([&] { fit_nrbf(C, w, nan_v); }), "nrbf: values must be finite");
  const auto f = fit_nrbf(C, w, V);
  EXPECT_EQ(failure_of([&] { evaluate_nrbf(f, MatrixXfR::Zero(1, 3)); }),
            "nrbf: queries must have 2 columns (r_u), got 3");
  EXPECT_EQ(failure_of([&] { nrbf_leave_one_out(C.topRows(1), w.head(1), V.topRows(1)); }),
            "nrbf: leave-one-out needs at least 2 samples, got 1");
  EXPECT_EQ(failure_of([&] {
              precompute::nrbf_widths(C, {0, 1, 7, 0}, C.topRows(2));
            }),
            "nrbf_widths: label 7 of node 2 is not a cluster 0..1");
}

}  // namespace
}  // namespace phasecast
