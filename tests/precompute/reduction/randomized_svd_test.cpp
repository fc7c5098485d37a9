// The randomized SVD against a full dense SVD (Eigen's BDCSVD, in double) on
// matrices of known spectrum.

#include "phasecast/precompute/reduction/randomized_svd.h"

#include "phasecast/core/dense_svd.h"

#include <gtest/gtest.h>
#include <Eigen/QR>

#include <cmath>
#include <random>

namespace phasecast::precompute {
namespace {

Eigen::MatrixXd random_orthonormal(Eigen::Index rows, Eigen::Index cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n;
  Eigen::MatrixXd G(rows, cols);
  for (Eigen::Index i = 0; i < G.size(); ++i) G.data()[i] = n(rng);
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(G);
  return qr.householderQ() * Eigen::MatrixXd::Identity(rows, cols);
}

struct KnownSpectrum {
  Eigen::MatrixXf A;
  Eigen::MatrixXd U;
  Eigen::VectorXd sigma;
};

// A = U diag(sigma) V^T with sigma_i = decay^i: the slow decay of cloth orbits.
KnownSpectrum known_spectrum(Eigen::Index M, Eigen::Index N, double decay) {
  KnownSpectrum k;
  const Eigen::Index n = std::min(M, N);
  k.U = random_orthonormal(M, n, 1);
  const Eigen::MatrixXd V = random_orthonormal(N, n, 2);
  k.sigma.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) k.sigma[i] = 10.0 * std::pow(decay, static_cast<double>(i));
  k.A = (k.U * k.sigma.asDiagonal() * V.transpose()).cast<float>();
  return k;
}

// Sine of the largest principal angle between span(A) and span(B) (orthonormal columns).
double subspace_sine(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  const Eigen::MatrixXd residual = B - A * (A.transpose() * B);
  return core::spectral_norm(residual);
}

TEST(RandomizedSvd, MatchesFullSvdOnAKnownSpectrum) {
  const auto k = known_spectrum(600, 400, 0.8);
  RandomizedSvdOptions o;
  o.rank = 12;
  o.block_columns = 64;
  const MatrixColumnSource source(k.A);
  const SvdResult r = randomized_svd(source, o);
  const Eigen::VectorXd full = core::singular_values(k.A.cast<double>());
  for (int i = 0; i < o.rank; ++i) {
    EXPECT_NEAR(r.sigma[i], full[i], 1e-3 * full[0]) << i;
    EXPECT_NEAR(r.sigma[i], k.sigma[i], 1e-3 * k.sigma[0]) << i;
  }
  EXPECT_LT(subspace_sine(k.U.leftCols(o.rank), r.U.cast<double>()), 1e-2);
  EXPECT_TRUE((r.U.transpose() * r.U).isIdentity(1e-4f));
  EXPECT_TRUE((r.V.transpose() * r.V).isIdentity(1e-4f));
  EXPECT_NEAR(r.frobenius_squared, k.sigma.squaredNorm(), 1e-4 * k.sigma.squaredNorm());
}

TEST(RandomizedSvd, ErrorIsWithinTheOptimalBound) {
  const auto k = known_spectrum(500, 300, 0.9);
  RandomizedSvdOptions o;
  o.rank = 20;
  const SvdResult r = randomized_svd(MatrixColumnSource(k.A), o);
  const Eigen::MatrixXf approx = r.U * r.sigma.asDiagonal() * r.V.transpose();
  const double error = (k.A - approx).norm();
  const double optimal = k.sigma.tail(k.sigma.size() - o.rank).norm();  // Eckart-Young
  EXPECT_LE(error, 1.05 * optimal);
  EXPECT_GE(error, 0.999 * optimal);
}

TEST(RandomizedSvd, DeterministicForASeedWhateverTheBlockSize) {
  const auto k = known_spectrum(200, 150, 0.7);
  RandomizedSvdOptions o;
  o.rank = 6;
  o.block_columns = 150;
  const SvdResult a = randomized_svd(MatrixColumnSource(k.A), o);
  const SvdResult b = randomized_svd(MatrixColumnSource(k.A), o);
  EXPECT_EQ(a.U, b.U);  // bit-identical rerun
  EXPECT_EQ(a.sigma, b.sigma);
  o.block_columns = 17;
  const SvdResult c = randomized_svd(MatrixColumnSource(k.A), o);
  EXPECT_TRUE(a.sigma.isApprox(c.sigma, 1e-5f));
}

TEST(RandomizedSvd, ReportsEveryPass) {
  const auto k = known_spectrum(50, 40, 0.5);
  RandomizedSvdOptions o;
  o.rank = 3;
  o.power_iterations = 2;
  int last = 0, total = 0;
  o.progress = [&](int pass, int passes) {
    EXPECT_EQ(pass, last + 1);
    last = pass;
    total = passes;
  };
  randomized_svd(MatrixColumnSource(k.A), o);
  EXPECT_EQ(last, 6);
  EXPECT_EQ(total, 6);
}

TEST(RandomizedSvd, RejectsEmptyAndBadRank) {
  const Eigen::MatrixXf empty(0, 0);
  EXPECT_THROW(randomized_svd(MatrixColumnSource(empty), {}), std::invalid_argument);
  const Eigen::MatrixXf A = Eigen::MatrixXf::Ones(4, 4);
  RandomizedSvdOptions o;
  o.rank = 0;
  EXPECT_THROW(randomized_svd(MatrixColumnSource(A), o), std::invalid_argument);
}

TEST(RankRule, LargestRankAboveTolerance) {
  Eigen::VectorXf s(6);
  s << 10, 5, 1, 0.5f, 0.1f, 0.01f;
  EXPECT_EQ(select_rank(s, 0.05), 4);  // 0.5 >= 0.5, 0.1 < 0.5
  EXPECT_EQ(select_rank(s, 0.01), 5);
  EXPECT_EQ(select_rank(s, 0.0), 6);
  EXPECT_EQ(select_rank(s, 0.9), 1);
}

TEST(RankRule, ErrorCurveIsTheFrobeniusTail) {
  Eigen::VectorXf s(3);
  s << 3, 2, 1;
  const double total = 9 + 4 + 1 + 0.25;  // one more sigma (0.5) not computed
  const Eigen::VectorXf e = relative_error_curve(s, total);
  EXPECT_NEAR(e[0], std::sqrt((4 + 1 + 0.25) / total), 1e-6);
  EXPECT_NEAR(e[1], std::sqrt((1 + 0.25) / total), 1e-6);
  EXPECT_NEAR(e[2], std::sqrt(0.25 / total), 1e-6);
}

}  // namespace
}  // namespace phasecast::precompute
