#pragma once
// Dimensional model reduction of radiance transfer fields (§4.2): subtract the
// mean field M-bar, SVD of the 48S x N_a data matrix A_a ~ U_a Q_a.

#include "phasecast/core/eigen_types.h"

#include <array>
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
  int resolved = 0;               // directions resolved (sigma_i > 1e-6 sigma_1): at most N_a - 1

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

// Fig. 12's red curve out of sample: the truncation error of held-out fields
// at every rank r = 1..K of the same SVD, K the directions it resolves, as
// |(I - U_r U_r^T) C|_2 / |C|_2 with C the held-out fields less M-bar (the
// paper's relErr over those fields). Entry r_a - 1 is the held-out truncation
// of U_a itself; the last is what the clusters' whole span leaves, a floor no
// rank of this basis passes, so a target below it needs other samples, not a
// larger r_a.
//   @param[in] fields     #N_a by 48S: the fields `reduction` was made from
//   @param[in] reduction  reduce_transfer(fields, ...)
//   @param[in] held_out   #H by 48S: true fields at other state nodes
//   @return               K = reduction.resolved values (all 0 when the
//                         held-out fields equal M-bar; empty when H = 0, of
//                         any width, or K = 0)
// Stores no basis beyond r_a: direction i is A^T W^1/2 v_i / sigma_i, formed
// block by block and orthonormalised by the Cholesky QR step reduce_transfer
// takes (so that the first r_a span what U_a spans); |.|_2 of the residual
// comes from the H x H Gram matrix C C^T less the coordinates' outer products.
// Throws std::invalid_argument when the sizes disagree.
VectorXf held_out_truncation_curve(const Eigen::Ref<const MatrixXfR>& fields,
                                   const TransferReduction& reduction,
                                   const Eigen::Ref<const MatrixXfR>& held_out);
// Where a rank-r_a model's truncation error lives: the fields' variation
// about M-bar, A = M - M-bar, and what the basis leaves of it, R = (I - U_a U_a^T) A,
// summed over parts of the 48 values of each scene point.
struct PartOfResidual {
  double of_data = 0;      // the part's share of |A|_F^2
  double of_residual = 0;  // its share of |R|_F^2
  double relative = 0;     // |R_part|_F / |A_part|_F (0 where the part does not vary)
};
struct ResidualByPart {
  // Deformable scene points, then the others (props: they change only by
  // the shadows and light the deformables cast on them).
  std::array<PartOfResidual, 2> points;
  std::array<PartOfResidual, 4> bands;  // spherical-harmonic bands l = 0..3, all colours
  double relative = 0;                  // |R|_F / |A|_F over all parts
};

// Splits the truncation error of `fields` (#fields by 48S, as for
// reduce_transfer) about `mean` (48S) in the orthonormal basis `U_a`
// (48S x r_a) by point kind and SH band. With the clusters' fields and the
// paper's (equal-weight) M-bar and U_a, `relative` is their Frobenius
// relative error at r_a, rel_error[r_a - 1] (Fig. 12's curve).
//   @param[in] deformable  S flags: 1 for a point U_u moves
// Throws std::invalid_argument when the sizes disagree.
ResidualByPart residual_by_part(const Eigen::Ref<const MatrixXfR>& fields, const VectorXf& mean,
                                const MatrixXfR& U_a, const std::vector<std::uint8_t>& deformable);

}  // namespace phasecast::precompute
