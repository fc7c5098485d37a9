// The one compiled dense SVD against matrices whose factors are known in
// closed form, and its refusal of a matrix that is not finite.

#include "phasecast/core/dense_svd.h"

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace phasecast::core {
namespace {

// A = Q_l diag(sigma) Q_r^T from two rotations by known angles: 3 x 2 and
// 40 x 20 (above Eigen's Jacobi threshold of 16 columns, so the
// divide-and-conquer path runs too).
Eigen::MatrixXd known(int rows, int cols, const Eigen::VectorXd& sigma) {
  Eigen::MatrixXd L = Eigen::MatrixXd::Identity(rows, rows), R = Eigen::MatrixXd::Identity(cols, cols);
  for (int k = 0; k + 1 < rows; ++k) {  // a product of plane rotations: orthogonal by construction
    const double a = 0.3 + 0.1 * k;
    Eigen::MatrixXd G = Eigen::MatrixXd::Identity(rows, rows);
    G(k, k) = G(k + 1, k + 1) = std::cos(a);
    G(k, k + 1) = -std::sin(a), G(k + 1, k) = std::sin(a);
    L = G * L;
  }
  for (int k = 0; k + 1 < cols; ++k) {
    const double a = 0.7 - 0.02 * k;
    Eigen::MatrixXd G = Eigen::MatrixXd::Identity(cols, cols);
    G(k, k) = G(k + 1, k + 1) = std::cos(a);
    G(k, k + 1) = -std::sin(a), G(k + 1, k) = std::sin(a);
    R = G * R;
  }
  return L.leftCols(cols) * sigma.asDiagonal() * R.transpose();
}

TEST(DenseSvd, RecoversAKnownSpectrumAndFactors) {
  for (const int cols : {2, 20}) {
    const int rows = 2 * cols;
    Eigen::VectorXd sigma(cols);
    for (int i = 0; i < cols; ++i) sigma[i] = std::pow(0.7, i) * 5;
    const Eigen::MatrixXd A = known(rows, cols, sigma);
    const DenseSvd svd = dense_svd(A);
    ASSERT_EQ(svd.U.rows(), rows);
    ASSERT_EQ(svd.U.cols(), cols);
    ASSERT_EQ(svd.V.rows(), cols);
    EXPECT_TRUE(svd.sigma.isApprox(sigma, 1e-12)) << cols;
    EXPECT_TRUE((svd.U * svd.sigma.asDiagonal() * svd.V.transpose()).isApprox(A, 1e-12)) << cols;
    EXPECT_TRUE((svd.U.transpose() * svd.U).isIdentity(1e-12)) << cols;
    EXPECT_NEAR(spectral_norm(A), 5.0, 1e-12) << cols;
    EXPECT_TRUE(singular_values(A).isApprox(sigma, 1e-12)) << cols;
  }
}

TEST(DenseSvd, ComputesOnlyTheVectorsAskedFor) {
  const Eigen::MatrixXd A = known(6, 3, Eigen::Vector3d(3, 2, 1));
  const DenseSvd left = dense_svd(A, SvdVectors::left), right = dense_svd(A, SvdVectors::right);
  EXPECT_EQ(left.U.cols(), 3);
  EXPECT_EQ(left.V.size(), 0);
  EXPECT_EQ(right.U.size(), 0);
  EXPECT_EQ(right.V.cols(), 3);
  EXPECT_EQ(dense_svd(A, SvdVectors::none).U.size(), 0);
  EXPECT_EQ(spectral_norm(Eigen::MatrixXd(0, 0)), 0.0);
}

TEST(DenseSvd, RefusesAMatrixThatIsNotFinite) {
  Eigen::MatrixXd A = known(40, 20, Eigen::VectorXd::LinSpaced(20, 20, 1));
  A(3, 4) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(dense_svd(A), std::invalid_argument);
  A(3, 4) = 0;
  A(3, 1) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(singular_values(A.leftCols(3)), std::invalid_argument);  // the Jacobi path too
}

}  // namespace
}  // namespace phasecast::core
