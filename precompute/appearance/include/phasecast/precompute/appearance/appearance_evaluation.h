#pragma once
// The appearance model measured against held-out truth: the transfer
// ray-cast at state nodes that are not cluster representatives, against
// what a client draws there (M-bar + U_a q_a(q_u)). The figures, their spread
// over the draw of nodes, paired comparisons of two models, the floors no
// rank-r_a model passes, and a basis from other states to compare with.

#include "phasecast/core/package.h"
#include "phasecast/precompute/appearance/appearance_fit.h"

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

namespace phasecast::precompute {

// How many of H held-out nodes pick the model (the first ones); the others
// report its error and never choose.
inline size_t held_out_picking_count(size_t H) {
  return (H + 1) / 2;
}

// True transfer at state nodes that are not cluster representatives: the
// independent truth the served appearance M-bar + U_a q_a(q_u) is measured
// against (§4.2 truncation plus §4.3 interpolation).
struct HeldOutTruth {
  std::vector<std::int32_t> nodes;  // H state nodes
  MatrixXfR fields;                 // H x 48S: their transfer, computed like the clusters'
};

// Relative errors of the served transfer over a set of held-out nodes, each
// sqrt(sum over nodes of |error|^2 / sum of |M - M-bar|^2), so that
// total^2 = truncation^2 + interpolation^2; of_transfer divides by sum |M|^2.
struct TruthError {
  double total = 0;          // |M - (M-bar + U_a q_a(q_u))|
  double truncation = 0;     // |M - M-bar - U_a U_a^T (M - M-bar)|: the best rank r_a can do
  double interpolation = 0;  // |U_a^T (M - M-bar) - q_a(q_u)|: what the interpolant adds
  double of_transfer = 0;    // total relative to |M| instead of |M - M-bar|
  // The same errors in the paper's relErr (§2.3.1, Table 1): the relative l2
  // (spectral) norm of the error matrix over the nodes, |E|_2 / |M - M-bar|_2,
  // whose columns are the nodes. On the clusters themselves the truncation is
  // exactly sigma_{r_a+1} / sigma_1, the figure the paper reports.
  double l2_total = 0;
  double l2_truncation = 0;
  // The best any rank-r_a model about this M-bar reaches at these nodes,
  // whatever its basis or interpolant: sigma_{r_a+1} / sigma_1 of the centred
  // truth M - M-bar itself (Eckart-Young in the spectral norm), a lower bound
  // of l2_truncation and l2_total. What l2_truncation has above it, this
  // basis misses. Clusters with another mean have another floor (both the
  // bound and its denominator move with M-bar). 0 when the nodes are no more
  // than r_a.
  double l2_floor = 0;
  // The total relative to the nodes' own variation, |M - mean_H M| with
  // mean_H their mean, in Frobenius and relative l2 norms: a denominator no
  // model moves, so models with different M-bar compare (the figures above
  // read better when M-bar lies far from the nodes, as |M - M-bar| grows).
  double of_variation = 0, l2_of_variation = 0;
  // sigma_{r_a+1} / sigma_1 of M - mean_H M: the least l2_of_variation of any
  // rank-r_a model whatever its mean, fitted to these very nodes (with E its
  // error and J the centring over nodes, E J = M J less a rank-r_a matrix,
  // and |E|_2 >= |E J|_2).
  double l2_floor_of_variation = 0;
  // |M - (M-bar + U_a q_a(q_u))|^2 at each node, in their order: what a
  // paired comparison of two models at the same nodes needs (paired_gain).
  Eigen::VectorXd node_error2;
};

// How much less squared error `candidate` leaves than `baseline` at the same
// nodes, as a fraction of the baseline's (gain < 0: more), and the noise of
// that fraction: the half-width of its two-sided 95 % Student t interval
// (t_0.975 with n - 1 degrees of freedom: 12.7 at 2 nodes, 2.09 at 20, 1.98
// at 100) times its standard error from the spread of the per-node
// differences (n - 1 in the variance), the baseline's total taken as fixed.
// With fewer than two nodes the noise is infinite: nothing can be told apart.
struct PairedGain {
  double gain = 0;
  double noise = 0;
  bool beyond_noise() const { return gain > noise; }
};
PairedGain paired_gain(const Eigen::VectorXd& baseline, const Eigen::VectorXd& candidate);

// Errors of the reduction's basis with q_a = served (H x r_a) at truth's nodes.
TruthError truth_error(const TransferReduction& reduction, const HeldOutTruth& truth,
                       const Eigen::Ref<const MatrixXfR>& served);

// How far the relative l2 figures move with the draw of nodes: their 10th and
// 90th percentiles over `draws` bootstrap resamples of the H nodes (H drawn
// with replacement, seeded). The spread the figures would show over a fresh
// draw of as many nodes, without computing a single further transfer.
struct TruthErrorSpread {
  std::array<double, 2> l2_total{0, 0};
  std::array<double, 2> l2_truncation{0, 0};
  // l2_of_variation, each resample centred on its own mean; none when no
  // resample varies. Not steadier than the figures about M-bar (measured:
  // about as wide or wider, since a resample of nodes alike has little
  // variation of its own to divide by).
  std::optional<std::array<double, 2>> l2_of_variation;
};
TruthErrorSpread truth_error_spread(const TransferReduction& reduction, const HeldOutTruth& truth,
                                    const Eigen::Ref<const MatrixXfR>& served, int draws = 199,
                                    std::uint64_t seed = 1);

// Is the truncation at the held-out states the clusters' fault? Two bases of
// rank r_a measured at the reported half (the served one and one fitted to
// the picking half's own true fields, equal weights about their own mean:
// states drawn at random, not cluster representatives), with q_a the exact
// projection, so `total` is each basis's truncation alone. Compare them by
// of_variation and l2_of_variation, whose denominator no mean moves, and by
// the paired gain. When the drawn basis is not better beyond the noise,
// other states of that count would not help: the states' transfer has more
// directions than r_a.
struct BasisComparison {
  TruthError served;  // the clusters' basis, as served
  TruthError drawn;   // the picking half's own basis
  int drawn_fields = 0;
  // The squared truncation the drawn basis saves over the clusters' at the
  // reported nodes, with its 95 % t interval (paired_gain, the clusters'
  // basis the baseline; < 0: the drawn one leaves more).
  PairedGain drawn_gain;
};

// Of `reduction` (the served basis) at `test`, against a basis of the same
// rank from `picking`'s fields; none when r_a is 0, `test` has fewer than two
// nodes, or `picking` resolves fewer than r_a directions (it needs more than
// r_a fields that differ). Throws std::invalid_argument when a field's width
// is not M-bar's.
std::optional<BasisComparison> compare_with_drawn_basis(const TransferReduction& reduction,
                                                        const HeldOutTruth& picking,
                                                        const HeldOutTruth& test);

// How held_out_target set r_a.
struct HeldOutRankChoice {
  double target = 0;      // the truncation asked for
  int rank = 0;           // r_a chosen: the least rank reaching it, else all the directions
  double truncation = 0;  // the picking half's truncation at that rank
  bool reached = false;   // false: no rank of the clusters reaches the target
  int picking_nodes = 0;  // the held-out nodes it was measured at
};

// The least rank whose truncation alone at the picking nodes (relative l2)
// is at most `target`, by the paper's equal-weight SVD of `fields`; all the
// resolved directions when none is. Throws std::invalid_argument without
// picking nodes.
HeldOutRankChoice rank_for_held_out_target(const Eigen::Ref<const MatrixXfR>& fields,
                                           const HeldOutTruth& picking, double target);

// The package's held-out figures (/appearance/held_out/) of the served model
// at the reported nodes `test`: its errors there, the clusters' own
// truncation over as many of them, and the spread over resamples (none with
// fewer than two nodes).
core::HeldOutFigures held_out_figures(const TruthError& error, const HeldOutTruth& test,
                                      const TransferReduction& reduction,
                                      const std::optional<TruthErrorSpread>& spread);

}  // namespace phasecast::precompute
