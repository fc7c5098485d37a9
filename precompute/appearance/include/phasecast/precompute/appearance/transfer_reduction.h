#pragma once
// Dimensional model reduction of radiance transfer fields (§4.2): subtract the
// mean field M-bar, SVD of the 48S x N_a data matrix A_a ~ U_a Q_a.

#include "phasecast/core/eigen_types.h"

#include <cstdint>
#include <vector>

namespace phasecast::precompute {

struct TransferReductionOptions {
  double eps_a = 1e-3;  // r_a = number of sigma_i >= eps_a * sigma_1 (when rank == 0)
  int rank = 0;         // > 0: fixed r_a (capped by the resolvable rank)
};

struct TransferReduction {
  VectorXf mean_transfer;         // 48S: M-bar
  MatrixXfR U_a;                  // 48S x r_a orthonormal transfer basis
  MatrixXfR Q_a;                  // r_a x N_a: column j is q_a^j = U_a^T (M^j - M-bar)
  VectorXf singular_values;       // all N_a singular values of A_a W^1/2, decreasing
  VectorXf rel_error;             // N_a: relative Frobenius error of the rank-(i+1) model of A_a W^1/2
                                  // (Fig. 12, red, with equal weights)
  Eigen::MatrixXd right_vectors;  // N_a x N_a: V of A_a W^1/2 = U Sigma V^T, column i with sigma_i
  Eigen::VectorXd weights;        // N_a: W, the weight of each field (all 1: equal)

  int rank() const { return static_cast<int>(U_a.cols()); }
};

// Reduces N_a transfer fields.
//   @param[in] fields   #N_a by 48S: row j is the field M^j of cluster node j
//                       (the transpose of the paper's A_a before centring)
//   @param[in] options  eps_a or a fixed rank
//   @param[in] weights  #N_a positive weights W of the fields, mean 1 (empty:
//                       all 1, the paper's A_a). M-bar is their weighted mean
//                       and U_a, Sigma the SVD of A_a W^1/2, so a field that
//                       stands for more state nodes pulls the basis harder;
//                       Q_a stays the projection of each unweighted field.
//   @return             M-bar, U_a, Q_a, the singular values and the error curve
// Method: eigen-decomposition of the N_a x N_a Gram matrix (double), then
// U_a = A_a W^1/2 V Sigma^-1 re-orthonormalised by a Cholesky QR step; this needs
// only O(48 S N_a) memory. Singular values below 1e-6 sigma_1 are not
// resolved this way and are never kept. All fields identical: r_a = 0.
// Throws std::invalid_argument for an empty input, a row length that is not a
// multiple of 48, non-finite values, eps_a outside [0, 1], a negative rank or
// weights that are not N_a positive finite values.
TransferReduction reduce_transfer(const Eigen::Ref<const MatrixXfR>& fields,
                                  const TransferReductionOptions& options,
                                  const Eigen::VectorXd& weights = {});

// The clusters' own truncation error as a held-out error over the same
// columns is measured: |(I - U_a U_a^T) A_S|_2 / |A_S|_2, A_S the centred
// fields of the clusters in `subset` (indices into 0..N_a-1). Over all N_a
// with equal weights it is sigma_{r_a+1} / sigma_1, the paper's relErr
// (§2.3.1). Needs no field: A_S = U Sigma V_S^T W_S^-1/2, so both norms
// follow from Sigma, the weights and the rows S of V.
double cluster_truncation_l2(const TransferReduction& reduction, const std::vector<int>& subset);

// The same, as the median over `draws` random subsets of `columns` clusters
// (seeded, the same on every platform); columns >= N_a: all of them. A
// spectral ratio over a few columns reads higher than over many when the
// residual spreads over many directions: the data's leading direction adds
// up over columns and the residual's do not. So a held-out figure over H
// nodes compares with this at H, not with sigma_{r_a+1} / sigma_1.
double cluster_truncation_l2(const TransferReduction& reduction, int columns, int draws = 255,
                             std::uint64_t seed = 1);

}  // namespace phasecast::precompute
