#pragma once
// The interpolant of the reduced transfer coordinates q_a over q_u (§4.3),
// chosen by measurement (docs/transfer.md, "Choosing the interpolant"):
//
//   nrbf  the paper's regularized normalized RBFs (nrbf.h), with the width
//         scale and the regularization lambda picked by leave-one-out on the
//         N_a cluster samples;
//   knn   inverse-square-distance weighting of the k nearest cluster samples
//         in q_u, k picked the same way;
//   affine-knn  an affine map of q_u fitted to the samples by least squares,
//         plus knn of what it leaves at each sample. The transfer is mostly
//         linear in q_u (docs/transfer.md): the map carries that part across
//         the gaps between clusters, and knn only the remainder.
//   affine-knn-slope  the same, with the neighbours found in the map's image:
//         states are near when the map predicts them alike lighting, so a
//         coordinate that barely moves the transfer does not pick them.
//
// knn and affine-knn(-slope) reproduce every sample at its own centre, the NRBF
// nearly (lambda > 0). The appearance stage keeps the one whose error against
// held-out true transfer is lowest.

#include "phasecast/precompute/appearance/nrbf.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace phasecast::precompute {

enum class InterpolantKind { nrbf, knn, affine_knn, affine_knn_slope };
const char* interpolant_name(InterpolantKind kind);

// Whether the kind carries an affine map (Interpolant::affine).
bool has_affine_map(InterpolantKind kind);

struct Interpolant {
  InterpolantKind kind = InterpolantKind::nrbf;
  NrbfInterpolant nrbf;      // nrbf: the fit; knn: centres, samples as weights, widths 1
                             // (affine-knn: what the affine map leaves of them as weights)
  float width_scale = 1.0f;  // nrbf: widths = scale x cluster spread (nrbf_widths)
  int neighbours = 0;        // knn, affine-knn: k (affine-knn's ridge: nrbf.regularization)
  MatrixXfR affine;          // affine-knn(-slope): (1 + r_u) x r_a, q_a ~ [1 q_u] affine
  double leave_one_out = 0;  // relative leave-one-out error of this choice on the samples
};

// Tunes the NRBF: every width scale and regularization of the grids below,
// keeping the lowest relative leave-one-out error (ties: the earlier entry).
//   @param[in] q_u      #N by r_u all state nodes
//   @param[in] labels   #N cluster of each node
//   @param[in] centers  #N_a by r_u cluster nodes
//   @param[in] samples  #N_a by r_a q_a at each centre
//   @param[in] progress (optional) called with "appearance nrbf tuning", the
//                       grid points done and their count
Interpolant tune_nrbf(const Eigen::Ref<const MatrixXfR>& q_u, const std::vector<std::int32_t>& labels,
                      const Eigen::Ref<const MatrixXfR>& centers, const Eigen::Ref<const MatrixXfR>& samples,
                      const std::function<void(const char*, long, long)>& progress = {});

// Tunes k of the k-nearest-neighbour interpolant by leave-one-out.
Interpolant tune_knn(const Eigen::Ref<const MatrixXfR>& centers, const Eigen::Ref<const MatrixXfR>& samples);

// Where affine-knn looks for neighbours: in q_u (affine-knn) or in the map's
// image (affine-knn-slope).
enum class NeighbourMetric { state, slope };

// The affine map by least squares with a ridge on its slope (none: the
// least-norm one where fewer than 1 + r_u samples leave it open), plus knn of
// its remainders, neighbours found by `metric`; the ridge (kAffineRidges,
// kept in nrbf.regularization) and k by leave-one-out, each left-out sample
// predicted by a map refitted without it (and, in its image, neighbours
// measured with it).
Interpolant tune_affine_knn(const Eigen::Ref<const MatrixXfR>& centers,
                            const Eigen::Ref<const MatrixXfR>& samples,
                            NeighbourMetric metric = NeighbourMetric::state);

// The squared distance of affine-knn-slope (neighbours and their inverse-square
// weights) is |(x - y) B|^2 + eps |x - y|^2, B the map's r_u x r_a slope: q_u
// is mapped by [B, sqrt(eps) I]. The small
// eps = kSlopeIsotropy |B|_F^2 / r_u keeps apart states the map cannot tell
// apart (r_a < r_u leaves B a null space); with no slope at all, eps = 1.
Eigen::MatrixXd slope_metric(const Eigen::Ref<const Eigen::MatrixXd>& slope);
inline constexpr double kSlopeIsotropy = 1e-6;

// q_a at every row of q (#M by r_u); returns #M by r_a.
MatrixXfR evaluate_interpolant(const Interpolant& f, const Eigen::Ref<const MatrixXfR>& q);

inline constexpr float kNrbfWidthScales[] = {0.25f, 0.5f, 1.0f, 2.0f, 4.0f};
inline constexpr float kNrbfRegularizations[] = {1e-6f, 1e-4f, 1e-3f, 1e-2f, 1e-1f};
inline constexpr int kKnnNeighbours[] = {1, 2, 3, 4, 6, 8, 12, 16};
// Ridges of affine-knn's slope, times the samples' mean squared spread per
// q_u coordinate (0: plain least squares).
inline constexpr double kAffineRidges[] = {0.0, 1e-3, 1e-2, 1e-1, 1.0};

}  // namespace phasecast::precompute
