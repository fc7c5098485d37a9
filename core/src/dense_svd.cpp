#include "phasecast/core/dense_svd.h"

#include <Eigen/SVD>

#include <stdexcept>

namespace phasecast::core {

DenseSvd dense_svd(const Eigen::MatrixXd& A, SvdVectors vectors) {
  unsigned options = 0;
  if (vectors == SvdVectors::left || vectors == SvdVectors::both) options |= Eigen::ComputeThinU;
  if (vectors == SvdVectors::right || vectors == SvdVectors::both) options |= Eigen::ComputeThinV;
  const Eigen::BDCSVD<Eigen::MatrixXd> svd(A, options);
  // Eigen leaves the factors unset for a matrix with a NaN or an infinity.
  if (svd.info() != Eigen::Success)
    throw std::invalid_argument("dense_svd: the matrix has a NaN or infinite entry (expected finite values)");
  DenseSvd result;
  result.sigma = svd.singularValues();
  if (svd.computeU()) result.U = svd.matrixU();
  if (svd.computeV()) result.V = svd.matrixV();
  return result;
}

Eigen::VectorXd singular_values(const Eigen::MatrixXd& A) {
  return dense_svd(A, SvdVectors::none).sigma;
}

double spectral_norm(const Eigen::MatrixXd& A) {
  if (A.size() == 0) return 0;
  return singular_values(A)[0];
}

}  // namespace phasecast::core
