#pragma once
// Dimensional model reduction of radiance transfer fields (§4.2): subtract the
// mean field M-bar, SVD of the 48S x N_a data matrix A_a ~ U_a Q_a.

#include "phasecast/core/eigen_types.h"

namespace phasecast::precompute {

struct TransferReductionOptions {
  double eps_a = 1e-3;  // r_a = number of sigma_i >= eps_a * sigma_1 (when rank == 0)
  int rank = 0;         // > 0: fixed r_a (capped by the resolvable rank)
};

struct TransferReduction {
  VectorXf mean_transfer;    // 48S: M-bar
  MatrixXfR U_a;             // 48S x r_a orthonormal transfer basis
  MatrixXfR Q_a;             // r_a x N_a: column j is q_a^j = U_a^T (M^j - M-bar)
  VectorXf singular_values;  // all N_a singular values of A_a, decreasing
  VectorXf rel_error;        // N_a: relative Frobenius error of the rank-(i+1) model (Fig. 12, red)

  int rank() const { return static_cast<int>(U_a.cols()); }
};

// Reduces N_a transfer fields.
//   @param[in] fields   #N_a by 48S: row j is the field M^j of cluster node j
//                       (the transpose of the paper's A_a before centring)
//   @param[in] options  eps_a or a fixed rank
//   @return             M-bar, U_a, Q_a, the singular values and the error curve
// Method: eigen-decomposition of the N_a x N_a Gram matrix (double), then
// U_a = A_a V Sigma^-1 re-orthonormalised by a Cholesky QR step; this needs
// only O(48 S N_a) memory. Singular values below 1e-6 sigma_1 are not
// resolved this way and are never kept. All fields identical: r_a = 0.
// Throws std::invalid_argument for an empty input, a row length that is not a
// multiple of 48, non-finite values, eps_a outside [0, 1] or a negative rank.
TransferReduction reduce_transfer(const Eigen::Ref<const MatrixXfR>& fields,
                                  const TransferReductionOptions& options);

}  // namespace phasecast::precompute
