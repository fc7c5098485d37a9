#pragma once
// Regularized normalized radial basis functions (§4.3; Nelles 2000) that
// interpolate the reduced transfer coordinates q_a over q_u.
//
//   phi_j(q) = exp(-|q - c_j|^2 / (2 w_j^2)) / sum_i exp(-|q - c_i|^2 / (2 w_i^2))
//   q_a(q)   = sum_j phi_j(q) W_j                        (W_j: row j of the weights)
//
// The weights solve the regularized least-squares problem
//   (Phi^T Phi + lambda I) W = Phi^T Q_a^T,   Phi_ij = phi_j(c_i),
// so lambda = 0 interpolates the samples exactly and lambda > 0 trades
// exactness for smoothness (Tikhonov). Rows of Phi sum to 1, so lambda is on
// the scale of Phi^T Phi's diagonal (<= N_a); the default 1e-3 barely
// smooths. Normalization makes q_a a weighted mean of the W_j: far from all
// centres it tends to the nearest centre's weight instead of to zero.

#include "phasecast/core/eigen_types.h"

#include <cstdint>
#include <vector>

namespace phasecast::precompute {

inline constexpr float kDefaultNrbfRegularization = 1e-3f;

struct NrbfInterpolant {
  MatrixXfR centers;                                  // N_a x r_u: c_j, the cluster nodes' q_u
  VectorXf widths;                                    // N_a: w_j > 0
  MatrixXfR weights;                                  // N_a x r_a: W_j
  float regularization = kDefaultNrbfRegularization;  // lambda
};

// Widths from cluster spread: w_j = scale * sqrt(mean over members i of
// |q_i - c_j|^2), the RMS distance of cluster j's nodes to its centre. A
// cluster of one node (or of identical nodes) takes half the distance to the
// nearest other centre; if that is 0 too (a single centre), 1.
//   @param[in] q_u      #N by r_u all state nodes
//   @param[in] labels   #N cluster of each node (0..N_a-1)
//   @param[in] centers  #N_a by r_u
//   @param[in] scale    > 0
//   @return             #N_a widths
VectorXf nrbf_widths(const Eigen::Ref<const MatrixXfR>& q_u, const std::vector<std::int32_t>& labels,
                     const Eigen::Ref<const MatrixXfR>& centers, float scale = 1.0f);

// Fits the weights.
//   @param[in] centers         #N_a by r_u
//   @param[in] widths          #N_a positive
//   @param[in] values          #N_a by r_a: q_a at each centre (Q_a^T)
//   @param[in] regularization  lambda >= 0
// Throws std::invalid_argument for mismatched shapes, non-positive widths,
// negative lambda or non-finite values.
NrbfInterpolant fit_nrbf(const Eigen::Ref<const MatrixXfR>& centers, const Eigen::Ref<const VectorXf>& widths,
                         const Eigen::Ref<const MatrixXfR>& values,
                         float regularization = kDefaultNrbfRegularization);

// Evaluates q_a at every row of q (#M by r_u); returns #M by r_a.
MatrixXfR evaluate_nrbf(const NrbfInterpolant& f, const Eigen::Ref<const MatrixXfR>& q);

struct LeaveOneOut {
  VectorXf errors;      // N_a: |q_a predicted without sample j - q_a^j| at centre j
  double rms = 0;       // sqrt(mean errors^2)
  double relative = 0;  // sqrt(sum errors^2 / sum |q_a^j|^2); 0 when all q_a^j are 0
};

// Leave-one-out error of fit_nrbf on its own samples: each sample is
// predicted by the interpolant fitted to the other N_a - 1 (same widths).
// Needs N_a >= 2.
LeaveOneOut nrbf_leave_one_out(const Eigen::Ref<const MatrixXfR>& centers,
                               const Eigen::Ref<const VectorXf>& widths,
                               const Eigen::Ref<const MatrixXfR>& values,
                               float regularization = kDefaultNrbfRegularization);

}  // namespace phasecast::precompute
