#pragma once
// The appearance model of a package (§4): from the transfer fields computed
// at the k-means representatives of the state nodes, the reduced transfer
// basis (§4.2) and the NRBF interpolant of q_a over all state nodes (§4.3).
// It fills core::Appearance (/appearance/*) and /portrait/q_a.
//
// The stage runs in three steps; the middle one (transfer on each
// representative's unreduced deformed mesh from the orbit store) belongs to
// the pipeline that owns the orbits:
//   1. clusters = kmeans(q_u, {N_a, seed})
//   2. fields.row(j) = compute_transfer(mesh of node clusters.representatives[j]) flattened
//   3. model = fit_appearance_model(q_u, clusters, fields, options)

#include "phasecast/core/package.h"
#include "phasecast/precompute/appearance/kmeans.h"
#include "phasecast/precompute/appearance/nrbf.h"
#include "phasecast/precompute/appearance/transfer_reduction.h"

namespace phasecast::precompute {

struct AppearanceOptions {
  TransferReductionOptions reduction;                 // eps_a or fixed r_a
  float regularization = kDefaultNrbfRegularization;  // NRBF lambda
  float width_scale = 1.0f;                           // NRBF widths = scale x cluster spread
};

struct AppearanceModel {
  core::Appearance appearance;  // /appearance/*
  MatrixXfR q_a;                // N x r_a: /portrait/q_a, the NRBF at every state node
  LeaveOneOut leave_one_out;    // on the N_a cluster samples (empty when N_a == 1)
};

//   @param[in] q_u       #N by r_u all state nodes
//   @param[in] clusters  kmeans(q_u) result: labels and representatives
//   @param[in] fields    #N_a by 48S: transfer of representative j in row j
//                        (layout of compute_transfer's rows, flattened)
//   @param[in] options   reduction rank rule and NRBF parameters
// Throws std::invalid_argument when the shapes disagree.
AppearanceModel fit_appearance_model(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters,
                                     const Eigen::Ref<const MatrixXfR>& fields,
                                     const AppearanceOptions& options);

}  // namespace phasecast::precompute
