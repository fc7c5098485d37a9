// The affine-knn interpolant of q_a over q_u against closed forms: an affine
// function is carried exactly between samples, every sample is reproduced at
// its centre, and leave-one-out refits the map without the sample it predicts.

#include "phasecast/precompute/appearance/interpolant.h"

#include <gtest/gtest.h>
#include <Eigen/LU>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

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

// The interpolant written out by hand, a second reader of interpolant.cpp:
// the map about the means with a ridge on its slope (none: least norm), then
// inverse-square-distance weights of the k nearest remainders.
Eigen::MatrixXd map_by_hand(const MatrixXfR& centers, const MatrixXfR& samples, double ridge) {
  const Eigen::Index d = centers.cols();
  const Eigen::RowVectorXd x_mean = centers.cast<double>().colwise().mean();
  const Eigen::RowVectorXd y_mean = samples.cast<double>().colwise().mean();
  const Eigen::MatrixXd dX = centers.cast<double>().rowwise() - x_mean;
  const Eigen::MatrixXd dY = samples.cast<double>().rowwise() - y_mean;
  Eigen::MatrixXd map(1 + d, samples.cols());
  if (ridge > 0) {
    const Eigen::MatrixXd gram = dX.transpose() * dX;
    const Eigen::MatrixXd shifted =
        gram + ridge * gram.trace() / static_cast<double>(d) * Eigen::MatrixXd::Identity(d, d);
    map.bottomRows(d) = shifted.inverse() * dX.transpose() * dY;
  } else {
    map.bottomRows(d) = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(dX).solve(dY);
  }
  map.row(0) = y_mean - x_mean * map.bottomRows(d);
  return map;
}

// slope: neighbours by |(x - y) B|^2 + 1e-6 |B|_F^2 / r_u |x - y|^2, B the map's slope.
Eigen::RowVectorXd affine_knn_by_hand(const MatrixXfR& centers, const MatrixXfR& samples, double ridge, int k,
                                      const Eigen::RowVectorXd& q, Eigen::Index skip = -1,
                                      bool slope = false) {
  MatrixXfR fit_centers = centers, fit_samples = samples;
  if (skip >= 0) {  // the map without the skipped sample
    for (Eigen::Index i = skip; i + 1 < centers.rows(); ++i)
      fit_centers.row(i) = centers.row(i + 1), fit_samples.row(i) = samples.row(i + 1);
    fit_centers.conservativeResize(centers.rows() - 1, Eigen::NoChange);
    fit_samples.conservativeResize(samples.rows() - 1, Eigen::NoChange);
  }
  const Eigen::MatrixXd map = map_by_hand(fit_centers, fit_samples, ridge);
  const auto at = [&](const Eigen::RowVectorXd& x) {
    return Eigen::RowVectorXd(map.row(0) + x * map.bottomRows(x.size()));
  };
  const Eigen::MatrixXd B = map.bottomRows(q.size());
  const double eps = B.squaredNorm() > 0 ? 1e-6 * B.squaredNorm() / static_cast<double>(q.size()) : 1.0;
  const auto distance2 = [&](const Eigen::RowVectorXd& dx) {
    return slope ? (dx * B).squaredNorm() + eps * dx.squaredNorm() : dx.squaredNorm();
  };
  std::vector<std::pair<double, Eigen::Index>> d;
  for (Eigen::Index c = 0; c < centers.rows(); ++c)
    if (c != skip) d.emplace_back(distance2(centers.row(c).cast<double>() - q), c);
  std::sort(d.begin(), d.end());
  Eigen::RowVectorXd rest = Eigen::RowVectorXd::Zero(samples.cols());
  double total = 0;
  for (int i = 0; i < k && i < static_cast<int>(d.size()); ++i) {
    const auto c = d[static_cast<size_t>(i)].second;
    const double w = 1 / d[static_cast<size_t>(i)].first;
    rest += w * (samples.row(c).cast<double>() - at(centers.row(c).cast<double>()));
    total += w;
  }
  return at(q) + rest / total;
}

TEST(AffineKnn, CarriesAnAffineFunctionExactlyBetweenSamples) {
  const MatrixXfR centers = random_points(20, 4, 1), queries = random_points(50, 4, 2);
  const Interpolant f = tune_affine_knn(centers, affine_of(centers));
  EXPECT_EQ(f.kind, InterpolantKind::affine_knn);
  EXPECT_LT(f.leave_one_out, 1e-5);
  EXPECT_EQ(f.nrbf.regularization, 0) << "an exact affine function wants no ridge";
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

// Leave-one-out refits the map without the left-out sample: the stored
// figure is the one the hand-written interpolant gives when each sample is
// dropped from the map's fit and from the knn (with the ridge and k kept).
// With 1 + r_u samples a map fitted to all would pass through the left-out
// one, so a figure taken without the refit would read nearly 0.
TEST(AffineKnn, LeaveOneOutRefitsTheMapWithoutTheSample) {
  const MatrixXfR centers = random_points(5, 4, 5);
  MatrixXfR samples = random_points(5, 3, 6);
  for (const auto metric : {NeighbourMetric::state, NeighbourMetric::slope}) {
    const Interpolant f = tune_affine_knn(centers, samples, metric);
    const bool slope = metric == NeighbourMetric::slope;
    EXPECT_EQ(f.kind, slope ? InterpolantKind::affine_knn_slope : InterpolantKind::affine_knn);
    EXPECT_LT((evaluate_interpolant(f, centers) - samples).norm(), 1e-4f * samples.norm());
    double err2 = 0;
    for (Eigen::Index j = 0; j < 5; ++j) {
      const Eigen::RowVectorXd guess = affine_knn_by_hand(
          centers, samples, f.nrbf.regularization, f.neighbours, centers.row(j).cast<double>(), j, slope);
      err2 += (guess - samples.row(j).cast<double>()).squaredNorm();
    }
    EXPECT_NEAR(f.leave_one_out, std::sqrt(err2 / samples.cast<double>().squaredNorm()), 1e-5) << slope;
    EXPECT_GT(f.leave_one_out, 0.05);
    // And what it serves off the samples is the hand-written interpolant too.
    const MatrixXfR queries = random_points(10, 4, 7);
    const MatrixXfR served = evaluate_interpolant(f, queries);
    for (Eigen::Index i = 0; i < 10; ++i) {
      const Eigen::RowVectorXd want = affine_knn_by_hand(
          centers, samples, f.nrbf.regularization, f.neighbours, queries.row(i).cast<double>(), -1, slope);
      EXPECT_LT((served.row(i).cast<double>() - want).norm(), 1e-4 * (1 + want.norm()))
          << "query " << i << " slope " << slope;
    }
  }
  // Fewer samples than unknowns: the least-norm map still passes through them.
  const Interpolant few = tune_affine_knn(centers.topRows(3), samples.topRows(3));
  EXPECT_LT((evaluate_interpolant(few, centers.topRows(3)) - samples.topRows(3)).norm(),
            1e-4f * samples.topRows(3).norm());
  // One sample: a constant (the slope is left open, and the least-norm one is 0).
  for (const auto metric : {NeighbourMetric::state, NeighbourMetric::slope}) {
    const Interpolant one = tune_affine_knn(centers.topRows(1), samples.topRows(1), metric);
    EXPECT_EQ(one.leave_one_out, 0);
    EXPECT_LT((evaluate_interpolant(one, centers.bottomRows(1)) - samples.topRows(1)).norm(), 1e-5f);
  }
}

// q_a turns with the first coordinate only, while the second spreads ten
// times wider and moves nothing: neighbours in q_u are mostly picked by the
// second, neighbours in the map's image by the first. The image metric reads
// better in leave-one-out and serves new states far better.
TEST(AffineKnn, NeighboursInTheMapsImageIgnoreACoordinateThatMovesNothing) {
  const auto spread = [](MatrixXfR q) {
    q.col(1) *= 10.0f;
    return q;
  };
  const MatrixXfR centers = spread(random_points(60, 2, 21)), queries = spread(random_points(300, 2, 22));
  const auto truth = [](const MatrixXfR& q) {
    MatrixXfR out(q.rows(), 2);
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      const float x = q(i, 0);
      out.row(i) << x + 0.5f * std::sin(4 * x), 0.3f * std::cos(3 * x);
    }
    return out;
  };
  const MatrixXfR samples = truth(centers), want = truth(queries);
  const Interpolant slope = tune_affine_knn(centers, samples, NeighbourMetric::slope);
  EXPECT_EQ(slope.kind, InterpolantKind::affine_knn_slope);
  const Interpolant state = tune_affine_knn(centers, samples);
  EXPECT_EQ(state.kind, InterpolantKind::affine_knn);
  EXPECT_LT(slope.leave_one_out, state.leave_one_out);
  const float slope_error = (evaluate_interpolant(slope, queries) - want).norm() / want.norm();
  const float state_error = (evaluate_interpolant(state, queries) - want).norm() / want.norm();
  EXPECT_GT(slope_error, 1e-4f) << "not vacuous: the function is not affine";
  EXPECT_LT(slope_error, 0.5f * state_error) << slope_error << " vs " << state_error;
  EXPECT_STREQ(interpolant_name(slope.kind), "affine-knn-slope");
}

// 12 noisy samples of an affine function of 8 coordinates: the plain fit
// has 9 unknowns per output and follows the noise. Leave-one-out picks a
// ridge, and the ridged map serves new points better than the plain one.
TEST(AffineKnn, LeaveOneOutPicksARidgeWhereTheSamplesBarelyFixTheMap) {
  const MatrixXfR centers = random_points(12, 8, 11), queries = random_points(400, 8, 12);
  const auto truth = [](const MatrixXfR& q) {  // q_a = 0.3 (sum of q) in 2 outputs
    MatrixXfR out(q.rows(), 2);
    for (Eigen::Index i = 0; i < q.rows(); ++i) out.row(i).setConstant(0.3f * q.row(i).sum());
    return out;
  };
  MatrixXfR samples = truth(centers);
  samples += 0.6f * random_points(12, 2, 13);  // noise of about the signal's size
  const Interpolant f = tune_affine_knn(centers, samples);
  EXPECT_GT(f.nrbf.regularization, 0) << "leave-one-out kept the plain fit";
  // The same k, no ridge: what the plain least-squares map would serve.
  Interpolant plain = f;
  const Eigen::MatrixXd map = map_by_hand(centers, samples, 0);
  plain.affine = map.cast<float>();
  Eigen::MatrixXd X(12, 9);
  X.col(0).setOnes();
  X.rightCols(8) = centers.cast<double>();
  plain.nrbf.weights = (samples.cast<double>() - X * map).cast<float>();
  const MatrixXfR want = truth(queries);
  const float ridged = (evaluate_interpolant(f, queries) - want).norm();
  const float unridged = (evaluate_interpolant(plain, queries) - want).norm();
  EXPECT_LT(ridged, unridged) << "ridged " << ridged << " vs plain " << unridged;
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
  Interpolant no_map = tune_affine_knn(centers, random_points(5, 3, 8), NeighbourMetric::slope);
  no_map.affine.resize(0, 0);
  try {
    evaluate_interpolant(no_map, random_points(2, 4, 9));
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "affine-knn-slope: expected a 5 x 3 affine map (1 + r_u, r_a), got 0 x 0");
  }
}

}  // namespace
}  // namespace phasecast
