#pragma once
// The appearance model a package holds (§4.2-4.3): from the transfer fields
// computed at the k-means representatives of the state nodes, the reduced
// transfer basis (§4.2, reduce_transfer in transfer_reduction.h) and the
// interpolant of q_a over q_u (§4.3), written into core::Appearance.
// Measuring a model against held-out truth is appearance_evaluation.h;
// choosing among candidate models by that measure is transfer_appearance.h.

#include "phasecast/core/package.h"
#include "phasecast/precompute/appearance/interpolant.h"
#include "phasecast/precompute/appearance/kmeans.h"
#include "phasecast/precompute/appearance/transfer_reduction.h"

#include <functional>
#include <vector>

namespace phasecast::precompute {

// best: the lowest held-out error of all four (else of leave-one-out)
enum class InterpolantChoice { best, nrbf, knn, affine_knn, affine_knn_slope };

// The weights M-bar and the SVD of §4.2 give the N_a cluster fields: equal,
// as in the paper, or each cluster's share of the state nodes, so that the
// basis and M-bar follow the states the server will show rather than the
// clusters (k-means gives rare outlying states a cluster each).
enum class TransferWeighting { equal, cluster_size };
// best: cluster sizes when their held-out gain over equal weights is beyond
// its noise (paired_gain), else the paper's equal weights.
enum class WeightingChoice { best, equal, cluster_size };
const char* weighting_name(TransferWeighting weighting);  // "equal", "cluster size"

// Cluster j's share of the state nodes, scaled to mean 1 (a representative
// stands at least for itself). Throws std::invalid_argument for a label
// outside 0..N_a-1.
Eigen::VectorXd cluster_size_weights(const KMeansResult& clusters);

// q_u of each cluster's representative: the interpolants' centres (N_a x r_u).
// Throws std::invalid_argument for a representative that is not a node of q_u.
MatrixXfR cluster_centers(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters);

// The interpolants `choice` names (all four for best), each tuned by
// leave-one-out on the N_a samples (q_a^j at centre j, N_a x r_a).
std::vector<Interpolant> tune_interpolants(const Eigen::Ref<const MatrixXfR>& q_u,
                                           const KMeansResult& clusters, const MatrixXfR& centers,
                                           const MatrixXfR& samples, InterpolantChoice choice,
                                           const std::function<void(const char*, long, long)>& progress);

// /appearance of a package from its basis (M-bar, U_a), the weighting that
// made it, its interpolant and the cluster nodes; the spectrum and the
// held-out figures are set apart.
void store_model(core::Appearance& appearance, const TransferReduction& reduction,
                 TransferWeighting weighting, const Interpolant& interpolant, const KMeansResult& clusters);

}  // namespace phasecast::precompute
