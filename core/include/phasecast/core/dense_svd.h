#pragma once
// A dense SVD by Eigen's divide-and-conquer BDCSVD (Jacobi below 16 columns),
// compiled once here. Instantiating BDCSVD costs about 40 s of compile time
// in every translation unit that names it; the randomized SVD's small core
// (§3.1) and the tests' independent readers call these instead.

#include <Eigen/Core>

namespace phasecast::core {

// Which singular vectors to compute besides the singular values.
enum class SvdVectors { none, left, right, both };

// A = U diag(sigma) V^T, thin: U is m x k and V is n x k with k = min(m, n),
// each empty unless asked for; sigma is decreasing.
struct DenseSvd {
  Eigen::MatrixXd U;
  Eigen::VectorXd sigma;
  Eigen::MatrixXd V;
};

DenseSvd dense_svd(const Eigen::MatrixXd& A, SvdVectors vectors = SvdVectors::both);

// sigma of A, decreasing.
Eigen::VectorXd singular_values(const Eigen::MatrixXd& A);

// The largest singular value, the l2 (spectral) norm; 0 for an empty A.
double spectral_norm(const Eigen::MatrixXd& A);

}  // namespace phasecast::core
