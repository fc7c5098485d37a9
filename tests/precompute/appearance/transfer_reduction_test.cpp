// Transfer SVD (§4.2) on fields of known rank, against Eigen's dense SVD.

#include "phasecast/precompute/appearance/transfer_reduction.h"

#include "phasecast/core/dense_svd.h"

#include <gtest/gtest.h>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

namespace phasecast {
namespace {

using precompute::reduce_transfer;
using precompute::TransferReductionOptions;

// N_a = 12 fields over S = 5 points: a mean plus 3 fixed directions with
// integer entries and integer amplitudes, so the float data are exact and the
// rank is exactly 3.
MatrixXfR rank3_fields() {
  std::mt19937_64 rng(9);
  auto integer = [&](int half) {
    return static_cast<int>(rng() % static_cast<std::uint64_t>(2 * half + 1)) - half;
  };
  const int n = 48 * 5, Na = 12;
  Eigen::MatrixXd B(n, 3);
  Eigen::VectorXd mean(n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < 3; ++j) B(i, j) = integer(3);
    mean[i] = integer(8);
  }
  MatrixXfR X(Na, n);
  for (int j = 0; j < Na; ++j) {
    const Eigen::VectorXd f = mean + B * Eigen::Vector3d(8 * integer(5), 3 * integer(5), integer(5));
    X.row(j) = f.transpose().cast<float>();
  }
  return X;
}

// Singular values of the centred data matrix A_a (48S x N_a) by a dense SVD.
Eigen::VectorXd dense_sigma(const MatrixXfR& X) {
  const Eigen::MatrixXd A = (X.rowwise() - X.colwise().mean()).transpose().cast<double>();
  return core::singular_values(A);
}

TEST(TransferReduction, KnownRankAndSingularValues) {
  const MatrixXfR X = rank3_fields();
  const auto r = reduce_transfer(X, {.eps_a = 1e-3});
  ASSERT_EQ(r.rank(), 3);
  ASSERT_EQ(r.U_a.rows(), X.cols());
  ASSERT_EQ(r.Q_a.rows(), 3);
  ASSERT_EQ(r.Q_a.cols(), X.rows());
  EXPECT_LT((r.mean_transfer.transpose() - X.colwise().mean()).norm(), 1e-5f);
  const Eigen::VectorXd sigma = dense_sigma(X);
  ASSERT_EQ(r.singular_values.size(), 12);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(r.singular_values[i], sigma[i], 1e-5 * sigma[0]);
  for (int i = 3; i < 12; ++i) EXPECT_LT(r.singular_values[i], 1e-6 * sigma[0]);
  // Orthonormal basis and exact reconstruction M^j = M-bar + U_a q_a^j.
  EXPECT_LT((r.U_a.transpose() * r.U_a - Eigen::MatrixXf::Identity(3, 3)).cwiseAbs().maxCoeff(), 1e-5f);
  const MatrixXfR rebuilt = (r.U_a * r.Q_a).transpose().rowwise() + r.mean_transfer.transpose();
  EXPECT_LT((rebuilt - X).cwiseAbs().maxCoeff(), 1e-3f);  // entries up to ~100
  EXPECT_LT(r.rel_error[2], 1e-3f);
  const double total = r.singular_values.cast<double>().squaredNorm();
  EXPECT_NEAR(r.rel_error[0], std::sqrt(r.singular_values.cast<double>().tail(11).squaredNorm() / total),
              1e-6);
}

TEST(TransferReduction, FixedRankMatchesTheErrorCurve) {
  const MatrixXfR X = rank3_fields();
  const auto r = reduce_transfer(X, {.eps_a = 0, .rank = 2});
  ASSERT_EQ(r.rank(), 2);
  const Eigen::MatrixXd centred = (X.rowwise() - r.mean_transfer.transpose()).cast<double>();
  const Eigen::MatrixXd residual = centred - (r.U_a * r.Q_a).transpose().cast<double>();
  EXPECT_NEAR(residual.norm() / centred.norm(), r.rel_error[1], 1e-5);
  EXPECT_EQ(reduce_transfer(X, {.eps_a = 0, .rank = 10}).rank(), 3);  // beyond the resolvable rank
  const Eigen::VectorXd sigma = dense_sigma(X);
  const double eps = (sigma[1] / sigma[0] + sigma[2] / sigma[0]) / 2;  // between sigma_2 and sigma_3
  EXPECT_EQ(reduce_transfer(X, {.eps_a = eps}).rank(), 2);
}

TEST(TransferReduction, IdenticalFieldsHaveRankZero) {
  const MatrixXfR X = MatrixXfR::Constant(4, 96, 0.25f);
  const auto r = reduce_transfer(X, {});
  EXPECT_EQ(r.rank(), 0);
  EXPECT_EQ(r.Q_a.rows(), 0);
  EXPECT_EQ(r.Q_a.cols(), 4);
  EXPECT_EQ(r.singular_values.cwiseAbs().maxCoeff(), 0.0f);
  EXPECT_EQ(r.rel_error.cwiseAbs().maxCoeff(), 0.0f);
  EXPECT_EQ(r.mean_transfer, X.row(0).transpose());
}

// Spectral norm by a dense SVD: the second reader of the Gram-based figures.
double l2(const Eigen::MatrixXd& X) {
  return core::spectral_norm(X);
}

// |(I - U_a U_a^T) A|_2 / |A|_2 for centred columns A, directly.
double truncation_l2(const precompute::TransferReduction& r, const Eigen::MatrixXd& A) {
  const Eigen::MatrixXd U = r.U_a.cast<double>();
  return l2(A - U * (U.transpose() * A)) / l2(A);
}

// A standard normal from mt19937_64 by Box-Muller: std::normal_distribution's
// algorithm differs between standard libraries, this does not.
double normal(std::mt19937_64& rng) {
  const auto uniform = [&] { return (static_cast<double>(rng() >> 11) + 0.5) * 0x1.0p-53; };  // (0, 1)
  const double u = uniform(), v = uniform();
  return std::sqrt(-2 * std::log(u)) * std::cos(2 * M_PI * v);
}

// Fields drawn from a population whose spectrum falls slowly (sigma_k ~ k^-0.6
// over 120 directions), as our transfer's does: 48 x 40 floats per field.
// `lead` scales the first direction: at 6 it outweighs the rest, and the
// truncation of a rank-r basis reads low on those fields.
MatrixXfR flat_spectrum_fields(int count, std::uint64_t seed, double lead = 1) {
  static const Eigen::MatrixXd basis = [] {
    std::mt19937_64 rng(77);
    Eigen::MatrixXd g(48 * 40, 120);
    for (Eigen::Index i = 0; i < g.size(); ++i) g.data()[i] = static_cast<double>(rng() % 2001) / 1000.0 - 1;
    return Eigen::MatrixXd(Eigen::HouseholderQR<Eigen::MatrixXd>(g).householderQ() *
                           Eigen::MatrixXd::Identity(g.rows(), g.cols()));
  }();
  std::mt19937_64 rng(seed);
  MatrixXfR X(count, basis.rows());
  for (int j = 0; j < count; ++j) {
    Eigen::VectorXd c(basis.cols());
    for (Eigen::Index k = 0; k < c.size(); ++k)
      c[k] = normal(rng) * std::pow(1.0 + static_cast<double>(k), -0.6);
    c[0] *= lead;
    X.row(j) = (basis * c).transpose().cast<float>();
  }
  return X;
}

TEST(ClusterTruncation, OverAllClustersIsTheSigmaRatioAndOverASubsetMatchesADenseSvd) {
  const MatrixXfR X = flat_spectrum_fields(30, 4);
  const auto r = reduce_transfer(X, {.eps_a = 0, .rank = 5});
  const Eigen::MatrixXd A = (X.rowwise() - r.mean_transfer.transpose()).transpose().cast<double>();
  const double sigma_ratio = r.singular_values[5] / r.singular_values[0];
  EXPECT_NEAR(precompute::cluster_truncation_l2(r, 30), sigma_ratio, 1e-5);
  EXPECT_NEAR(precompute::cluster_truncation_l2(r, 99), sigma_ratio, 1e-5);  // more than N_a: all of them
  EXPECT_NEAR(truncation_l2(r, A), sigma_ratio, 1e-5);
  for (const std::vector<int>& subset : {std::vector<int>{3, 17, 0, 29, 8}, std::vector<int>{21},
                                         std::vector<int>{1, 2, 4, 6, 10, 12, 14, 16, 18, 20, 22, 24}}) {
    Eigen::MatrixXd columns(A.rows(), static_cast<Eigen::Index>(subset.size()));
    for (size_t i = 0; i < subset.size(); ++i) columns.col(static_cast<Eigen::Index>(i)) = A.col(subset[i]);
    EXPECT_NEAR(precompute::cluster_truncation_l2(r, subset), truncation_l2(r, columns), 1e-5);
  }
  EXPECT_THROW(precompute::cluster_truncation_l2(r, std::vector<int>{30}), std::invalid_argument);
  EXPECT_THROW(precompute::cluster_truncation_l2(r, 0), std::invalid_argument);
}

// The draws are random subsets, not the first columns: in half the clusters
// one direction outweighs the rest, so the first 8 columns read far higher
// than the last 8, and the median over draws is that of subsets drawn
// by another generator and measured by a dense SVD. Another seed, other draws.
TEST(ClusterTruncation, IsTheMedianOverRandomSubsets) {
  MatrixXfR X(60, 48 * 40);
  X << flat_spectrum_fields(30, 6), flat_spectrum_fields(30, 7, 6);
  const auto r = reduce_transfer(X, {.eps_a = 0, .rank = 6});
  const Eigen::MatrixXd A = (X.rowwise() - r.mean_transfer.transpose()).transpose().cast<double>();
  const auto dense = [&](const std::vector<int>& subset) {
    Eigen::MatrixXd columns(A.rows(), static_cast<Eigen::Index>(subset.size()));
    for (size_t i = 0; i < subset.size(); ++i) columns.col(static_cast<Eigen::Index>(i)) = A.col(subset[i]);
    return truncation_l2(r, columns);
  };
  const double first = dense({0, 1, 2, 3, 4, 5, 6, 7}), last = dense({52, 53, 54, 55, 56, 57, 58, 59});
  std::mt19937_64 rng(12345);
  std::vector<double> ratios;
  for (int d = 0; d < 255; ++d) {
    std::vector<int> all(60);
    std::iota(all.begin(), all.end(), 0);
    for (int i = 0; i < 8; ++i)
      std::swap(all[static_cast<size_t>(i)],
                all[static_cast<size_t>(i + static_cast<int>(rng() % static_cast<std::uint64_t>(60 - i)))]);
    ratios.push_back(dense(std::vector<int>(all.begin(), all.begin() + 8)));
  }
  std::nth_element(ratios.begin(), ratios.begin() + 127, ratios.end());
  const double median = ratios[127], ours = precompute::cluster_truncation_l2(r, 8);
  EXPECT_GT(first, 1.2 * median);
  EXPECT_LT(last, 0.8 * median);
  EXPECT_NEAR(ours, median, 0.05 * median) << "first 8: " << first << ", last 8: " << last;
  EXPECT_NE(ours, precompute::cluster_truncation_l2(r, 8, 255, 2));
  EXPECT_EQ(ours, precompute::cluster_truncation_l2(r, 8, 255, 1));  // seeded: the same draws
}

// Why the held-out figure is compared with the clusters' own figure over as
// many columns: fresh fields from the same population, projected on the basis
// of 200 samples, read far above sigma_{r+1} / sigma_1 over 10 columns and
// near it over 200 (the basis generalises: 200 samples of 120 directions); the
// clusters' figure over 10 of them comes near the first (it is in-sample, so a
// little lower).
TEST(ClusterTruncation, PredictsAHeldOutFigureOfTheSameSize) {
  const auto r = reduce_transfer(flat_spectrum_fields(200, 5), {.eps_a = 0, .rank = 8});
  const auto held_out = [&](int count, std::uint64_t seed) {
    const MatrixXfR Y = flat_spectrum_fields(count, seed);
    return truncation_l2(r, (Y.rowwise() - r.mean_transfer.transpose()).transpose().cast<double>());
  };
  const double sigma_ratio = r.singular_values[8] / r.singular_values[0];
  double few = 0;
  for (std::uint64_t seed = 100; seed < 110; ++seed) few += held_out(10, seed) / 10;  // mean of 10 draws
  const double alike = precompute::cluster_truncation_l2(r, 10);
  EXPECT_GT(few, 1.3 * sigma_ratio) << few << " vs " << sigma_ratio;
  EXPECT_GT(alike, 1.3 * sigma_ratio) << alike << " vs " << sigma_ratio;
  EXPECT_NEAR(few, alike, 0.35 * few) << few << " vs " << alike;
  const double many = held_out(200, 200);
  EXPECT_LT(many, 0.8 * few) << many << " vs " << few;
  EXPECT_NEAR(many, sigma_ratio, 0.35 * sigma_ratio) << "over as many columns, sigma_{r+1} / sigma_1";
}

// Weighting a field by an integer count is repeating it that many times: the
// weighted reduction matches the plain one of the repeated fields (the
// weights' scale only scales sigma), and the clusters' truncation measures the
// unweighted fields, read by a dense SVD.
TEST(WeightedTransferReduction, IsTheReductionOfRepeatedFields) {
  const MatrixXfR X = flat_spectrum_fields(10, 6);
  const std::vector<int> counts{1, 7, 2, 1, 3, 1, 1, 5, 1, 2};
  const int total = std::accumulate(counts.begin(), counts.end(), 0);
  MatrixXfR repeated(total, X.cols());
  Eigen::VectorXd weights(10);
  for (int j = 0, row = 0; j < 10; ++j) {
    weights[j] = counts[static_cast<size_t>(j)] * 10.0 / total;  // mean 1
    for (int k = 0; k < counts[static_cast<size_t>(j)]; ++k) repeated.row(row++) = X.row(j);
  }
  const auto w = reduce_transfer(X, {.eps_a = 0, .rank = 4}, weights);
  const auto plain = reduce_transfer(repeated, {.eps_a = 0, .rank = 4});
  EXPECT_LT((w.mean_transfer - plain.mean_transfer).norm(), 1e-5f * plain.mean_transfer.norm());
  EXPECT_GT((w.mean_transfer.transpose() - X.colwise().mean()).norm(), 0.1f * w.mean_transfer.norm())
      << "not vacuous: the weights move M-bar";
  const double scale = std::sqrt(10.0 / total);
  for (int i = 0; i < 10; ++i)
    EXPECT_NEAR(w.singular_values[i], scale * plain.singular_values[i], 1e-5 * w.singular_values[0]) << i;
  const Eigen::MatrixXd Pw = (w.U_a * w.U_a.transpose()).cast<double>();
  const Eigen::MatrixXd Pp = (plain.U_a * plain.U_a.transpose()).cast<double>();
  EXPECT_LT((Pw - Pp).norm(), 1e-4) << "the same subspace";
  // Q_a: each unweighted field's coordinates, as the interpolant needs them.
  const Eigen::MatrixXd A = (X.rowwise() - w.mean_transfer.transpose()).transpose().cast<double>();
  EXPECT_LT((w.Q_a.cast<double>() - w.U_a.cast<double>().transpose() * A).norm(), 1e-4 * A.norm());
  for (const std::vector<int>& subset : {std::vector<int>{1, 4, 7}, std::vector<int>{0, 2, 3, 5, 6, 8, 9},
                                         std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}}) {
    Eigen::MatrixXd columns(A.rows(), static_cast<Eigen::Index>(subset.size()));
    for (size_t i = 0; i < subset.size(); ++i) columns.col(static_cast<Eigen::Index>(i)) = A.col(subset[i]);
    EXPECT_NEAR(precompute::cluster_truncation_l2(w, subset), truncation_l2(w, columns), 1e-5);
  }
  // Equal weights are the paper's A_a (to round-off: the empty default keeps the plain mean's sums).
  const auto ones = reduce_transfer(X, {.eps_a = 0, .rank = 4}, Eigen::VectorXd::Ones(10));
  const auto none = reduce_transfer(X, {.eps_a = 0, .rank = 4});
  EXPECT_LT((ones.mean_transfer - none.mean_transfer).norm(), 1e-6f * none.mean_transfer.norm());
  EXPECT_LT((ones.U_a - none.U_a).norm(), 1e-5f);
}

// Fig. 12 out of sample, read by a second route: at every rank r, the
// reduction cut at r (its own U_a, orthonormalised apart) measured on the
// held-out fields directly. Equal and cluster-like weights; fresh fields of
// the same population read above the clusters' own sigma_{r+1} / sigma_1 past
// the leading directions.
TEST(HeldOutTruncationCurve, MatchesTheBasisOfEveryRankMeasuredDirectly) {
  const MatrixXfR X = flat_spectrum_fields(24, 8), Y = flat_spectrum_fields(9, 9);
  Eigen::VectorXd weights(24);
  for (int j = 0; j < 24; ++j) weights[j] = 0.25 + 0.125 * (j % 12);
  weights /= weights.mean();
  for (const Eigen::VectorXd& w : {Eigen::VectorXd(), weights}) {
    const auto full = reduce_transfer(X, {.eps_a = 0, .rank = 3}, w);
    const VectorXf curve = precompute::held_out_truncation_curve(X, full, Y);
    ASSERT_EQ(curve.size(), 23) << "N_a - 1 centred fields resolve N_a - 1 directions";
    const Eigen::MatrixXd C = (Y.rowwise() - full.mean_transfer.transpose()).transpose().cast<double>();
    for (int r = 1; r <= 23; ++r) {
      const auto cut = reduce_transfer(X, {.eps_a = 0, .rank = r}, w);
      EXPECT_NEAR(curve[r - 1], truncation_l2(cut, C), 2e-4) << "rank " << r;
      if (r >= 8 && r < 23) {  // past the leading directions the unseen fields read above the clusters
        EXPECT_GT(curve[r - 1], cut.singular_values[r] / cut.singular_values[0]) << "rank " << r;
      }
    }
    EXPECT_GT(curve[22], 0.3) << "the clusters' span leaves most of a 120-direction population";
  }
}

// Closed forms: a held-out field in the clusters' span leaves nothing once
// every direction is in; one orthogonal to it loses all at every rank; M-bar
// itself has nothing to lose.
TEST(HeldOutTruncationCurve, ClosedFormsAndBadSizes) {
  const MatrixXfR X = rank3_fields();
  const auto r = reduce_transfer(X, {.eps_a = 0, .rank = 1});
  const MatrixXfR inside = 0.5f * (X.row(2) + X.row(7));
  // M-bar plus e_0 less its part in the clusters' span.
  const Eigen::MatrixXd U = reduce_transfer(X, {.eps_a = 0, .rank = 3}).U_a.cast<double>();
  const Eigen::VectorXd e = Eigen::VectorXd::Unit(X.cols(), 0) - U * U.row(0).transpose();
  const MatrixXfR outside = (r.mean_transfer.cast<double>() + e / e.norm()).transpose().cast<float>();
  const VectorXf in = precompute::held_out_truncation_curve(X, r, inside);
  ASSERT_EQ(in.size(), 3) << "rank 3: three resolved directions";
  EXPECT_GT(in[0], 0.01f);
  EXPECT_NEAR(in[2], 0, 1e-3);
  const VectorXf out = precompute::held_out_truncation_curve(X, r, outside);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(out[i], 1, 1e-4) << i;
  const VectorXf none = precompute::held_out_truncation_curve(X, r, r.mean_transfer.transpose());
  EXPECT_EQ(none, VectorXf::Zero(3));
  EXPECT_EQ(precompute::held_out_truncation_curve(X, r, MatrixXfR(0, X.cols())).size(), 0);
  EXPECT_EQ(precompute::held_out_truncation_curve(X, r, MatrixXfR()).size(), 0);  // no nodes, no width
  EXPECT_THROW(precompute::held_out_truncation_curve(X, r, MatrixXfR::Zero(1, 48)), std::invalid_argument);
  EXPECT_THROW(precompute::held_out_truncation_curve(X.topRows(5), r, inside), std::invalid_argument);
}

std::string failure_of(const MatrixXfR& X, TransferReductionOptions o, const Eigen::VectorXd& weights = {}) {
  try {
    reduce_transfer(X, o, weights);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}

// Two points, the first deformable: it varies in one band-1 value, the prop
// in one band-3 value, less. A rank-1 basis takes the larger variation, so
// all that is left lives on the prop, in band 3.
TEST(ResidualByPart, PutsWhatTheBasisLeavesOnThePartThatVariesOutsideIt) {
  const Eigen::Vector4d a(3, -1, -4, 2), b(3, -1, 1, -3);  // of mean 0, orthogonal
  MatrixXfR X = MatrixXfR::Constant(4, 96, 0.5f);
  for (int j = 0; j < 4; ++j) {
    X(j, 1) += static_cast<float>(a[j]);            // point 0, red, coefficient 1 (l = 1)
    X(j, 48 + 16 + 9) += static_cast<float>(b[j]);  // point 1, green, coefficient 9 (l = 3)
  }
  const auto r = reduce_transfer(X, {.eps_a = 0, .rank = 1});
  const auto parts = precompute::residual_by_part(X, r.mean_transfer, r.U_a, {1, 0});
  const double A = a.squaredNorm(), B = b.squaredNorm();  // 30 and 20
  EXPECT_NEAR(parts.points[0].of_data, A / (A + B), 1e-6);
  EXPECT_NEAR(parts.points[0].of_residual, 0, 1e-6);
  EXPECT_NEAR(parts.points[0].relative, 0, 1e-4);
  EXPECT_NEAR(parts.points[1].of_data, B / (A + B), 1e-6);
  EXPECT_NEAR(parts.points[1].of_residual, 1, 1e-6);
  EXPECT_NEAR(parts.points[1].relative, 1, 1e-6);
  EXPECT_NEAR(parts.bands[1].of_data, A / (A + B), 1e-6);
  EXPECT_NEAR(parts.bands[3].of_residual, 1, 1e-6);
  for (size_t l : {0, 2}) EXPECT_EQ(parts.bands[l].of_data, 0) << "band " << l;
  EXPECT_NEAR(parts.relative, std::sqrt(B / (A + B)), 1e-6);
  EXPECT_NEAR(parts.relative, r.rel_error[0], 1e-6);  // the Frobenius relErr of Fig. 12
}

// A second reader: the dense residual A - U U^T A summed over masks of the
// 48S values, on fields that vary in every value (so every band boundary,
// k = 0|1, 3|4, 8|9, is crossed).
TEST(ResidualByPart, MatchesADenseResidualSummedByHand) {
  const MatrixXfR X = rank3_fields();
  const auto r = reduce_transfer(X, {.eps_a = 0, .rank = 2});
  const std::vector<std::uint8_t> deformable{1, 0, 1, 1, 0};
  const auto parts = precompute::residual_by_part(X, r.mean_transfer, r.U_a, deformable);
  const Eigen::MatrixXd A = (X.cast<double>().rowwise() - r.mean_transfer.cast<double>().transpose());
  const Eigen::MatrixXd U = r.U_a.cast<double>();
  const Eigen::MatrixXd R = A - A * U * U.transpose();
  const double data = A.squaredNorm(), residual = R.squaredNorm();
  const auto check = [&](const precompute::PartOfResidual& got, auto in_part, const std::string& name) {
    double a = 0, e = 0;
    for (Eigen::Index v = 0; v < A.cols(); ++v)
      if (in_part(v)) a += A.col(v).squaredNorm(), e += R.col(v).squaredNorm();
    ASSERT_GT(a, 0) << name << ": not vacuous";
    EXPECT_NEAR(got.of_data, a / data, 1e-6) << name;
    EXPECT_NEAR(got.of_residual, e / residual, 1e-4) << name;
    EXPECT_NEAR(got.relative, std::sqrt(e / a), 1e-4) << name;
  };
  for (int kind = 0; kind < 2; ++kind)
    check(
        parts.points[static_cast<size_t>(kind)],
        [&](Eigen::Index v) { return (deformable[static_cast<size_t>(v / 48)] == 1) == (kind == 0); },
        "point kind " + std::to_string(kind));
  const int first[] = {0, 1, 4, 9, 16};  // band l holds coefficients [l^2, (l+1)^2)
  for (int l = 0; l < 4; ++l)
    check(
        parts.bands[static_cast<size_t>(l)],
        [&](Eigen::Index v) { return v % 16 >= first[l] && v % 16 < first[l + 1]; },
        "band " + std::to_string(l));
  EXPECT_NEAR(parts.relative, std::sqrt(residual / data), 1e-5);
  EXPECT_NEAR(parts.relative, r.rel_error[1], 1e-5);
  EXPECT_GT(parts.relative, 0.01) << "not vacuous: rank 2 of 3";
  EXPECT_THROW(precompute::residual_by_part(X, r.mean_transfer, r.U_a, {1, 0}), std::invalid_argument);
}

TEST(TransferReductionRejects, BadInput) {
  EXPECT_EQ(failure_of(MatrixXfR::Zero(3, 50), {}),
            "reduce_transfer: fields must be N_a x 48S with N_a, S >= 1, got 3 x 50");
  EXPECT_EQ(failure_of(MatrixXfR::Zero(3, 48), {.eps_a = 2}),
            "reduce_transfer: eps_a must be in [0, 1], got 2");
  EXPECT_EQ(failure_of(MatrixXfR::Zero(3, 48), {.eps_a = 0, .rank = -1}),
            "reduce_transfer: rank must be >= 0, got -1");
  MatrixXfR X = MatrixXfR::Zero(3, 48);
  X(1, 7) = INFINITY;
  EXPECT_EQ(failure_of(X, {}), "reduce_transfer: field 1 has a non-finite value");
  const MatrixXfR Y = MatrixXfR::Zero(3, 48);
  EXPECT_EQ(failure_of(Y, {}, Eigen::VectorXd::Ones(2)),
            "reduce_transfer: expected 3 weights (one per field), got 2");
  EXPECT_EQ(failure_of(Y, {}, Eigen::Vector3d(1, 0, 2)),
            "reduce_transfer: weight 1 is 0, expected a positive finite value");
  EXPECT_EQ(failure_of(Y, {}, Eigen::Vector3d(1, 1, NAN)),
            "reduce_transfer: weight 2 is nan, expected a positive finite value");
}

}  // namespace
}  // namespace phasecast
