#pragma once
// The appearance model of a package (§4), chosen: the candidate bases
// (weightings, §4.2) and interpolants (§4.3) of appearance_fit.h, the first
// half of the held-out nodes picking one by appearance_evaluation.h's
// figures and the second half reporting it. It fills core::Appearance
// (/appearance/*) and /portrait/q_a.
//
// The stage runs in three steps; the middle one (transfer on each
// representative's unreduced deformed mesh from the orbit store) belongs to
// the pipeline that owns the orbits:
//   1. clusters = kmeans(q_u, {N_a, seed})
//   2. fields.row(j) = compute_transfer(mesh of node clusters.representatives[j]) flattened
//   3. model = fit_appearance_model(q_u, clusters, fields, options)

#include "phasecast/core/package.h"
#include "phasecast/precompute/appearance/appearance_evaluation.h"
#include "phasecast/precompute/appearance/appearance_fit.h"

#include <functional>
#include <optional>
#include <vector>

namespace phasecast::precompute {

struct AppearanceOptions {
  TransferReductionOptions reduction;  // eps_a or fixed r_a
  InterpolantChoice interpolant = InterpolantChoice::best;
  // best tries both weightings only with held-out truth to choose by: no
  // other figure compares two models with different M-bar.
  WeightingChoice weighting = WeightingChoice::best;
  // > 0: r_a is the least rank whose truncation alone at the picking half of
  // the held-out nodes (relative l2, the paper's equal-weight SVD) is at most
  // this, instead of the reduction's rule; the reported half never sees it.
  double held_out_target = 0;
  // Ticks of the NRBF's tuning, one per grid point: its leave-one-out refits
  // N_a - 1 samples N_a times (N_a^4 work, tens of minutes at N_a = 800).
  std::function<void(const char*, long, long)> progress = nullptr;
};

struct CandidateReport {
  Interpolant interpolant;                                 // tuned by leave-one-out on the N_a samples
  TransferWeighting weighting = TransferWeighting::equal;  // of the reduction it interpolates
  // On the first half of the held-out nodes: picks the candidate by its error
  // relative to |M| (a denominator no candidate moves; with one weighting,
  // the same order as total).
  TruthError selection;
  TruthError test;  // on the second half: reported, never used to choose
};

struct AppearanceModel {
  core::Appearance appearance;              // /appearance/*
  MatrixXfR q_a;                            // N x r_a: /portrait/q_a, the interpolant at every state node
  std::vector<CandidateReport> candidates;  // every weighting and interpolant tried; the chosen one first
  // The best cluster-size candidate's paired gain over the best equal one on
  // the picking half, when both were judged there; cluster sizes are kept
  // only when it is beyond its noise.
  std::optional<PairedGain> weighting_gain;
  std::optional<BasisComparison> basis_comparison;  // at the reported half (compare_with_drawn_basis)
  std::optional<HeldOutRankChoice> rank_choice;     // when options.held_out_target set r_a
};

//   @param[in] q_u       #N by r_u all state nodes
//   @param[in] clusters  kmeans(q_u) result: labels and representatives
//   @param[in] fields    #N_a by 48S: transfer of representative j in row j
//                        (layout of compute_transfer's rows, flattened)
//   @param[in] options   reduction rank rule, weighting and interpolant choice
//   @param[in] held_out  truth at other nodes (may be empty: the choice then
//                        falls to leave-one-out and no held-out error is stored)
// Throws std::invalid_argument when the shapes disagree, or when
// options.held_out_target is set with no picking node to measure it at.
AppearanceModel fit_appearance_model(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters,
                                     const Eigen::Ref<const MatrixXfR>& fields,
                                     const AppearanceOptions& options, const HeldOutTruth& held_out = {});

}  // namespace phasecast::precompute
