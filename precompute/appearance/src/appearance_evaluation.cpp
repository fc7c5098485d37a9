// The appearance model against held-out truth (appearance_evaluation.h).

#include "phasecast/precompute/appearance/appearance_evaluation.h"

#include "largest_eigenvalue.h"

#include <fmt/format.h>
#include <Eigen/Eigenvalues>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

// X^T X of a tall float matrix, summed in double over row blocks.
Eigen::MatrixXd gram(const Eigen::MatrixXf& X) {
  constexpr Eigen::Index kRows = 4096;
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(X.cols(), X.cols());
  for (Eigen::Index i = 0; i < X.rows(); i += kRows) {
    const Eigen::MatrixXd block = X.middleRows(i, std::min(kRows, X.rows() - i)).cast<double>();
    g.noalias() += block.transpose() * block;
  }
  return g;
}

// Nodes whose variation about their own mean is below this fraction of their
// deviation from M-bar are alike: what is left is the rounding of J G J.
constexpr double kNoVariation = 1e-12;

// J G J, J the centring over the nodes, of the Gram matrix G of M - M-bar:
// the Gram matrix of M - mean_H M, since centring over nodes removes M-bar
// ((M - M-bar) J = M J).
Eigen::MatrixXd centred_over_nodes(const Eigen::MatrixXd& gram) {
  const Eigen::Index H = gram.rows();
  const Eigen::MatrixXd J = Eigen::MatrixXd::Identity(H, H) - Eigen::MatrixXd::Constant(H, H, 1.0 / H);
  return J * gram * J;
}

// What both the figures and their spread are made of: per-node Frobenius sums
// and the H x H Gram matrices of the truncation residual T, the error and the
// centred truth. With P the best coordinates rank r_a has and S the served
// ones, M - M-bar = T + U P and the error is T + U (P - S), with T orthogonal
// to U_a, so every Gram matrix follows from T's and the coordinates.
struct HeldOutGrams {
  double centred2 = 0, truth2 = 0, total2 = 0, truncation2 = 0, interpolation2 = 0, variation2 = 0;
  Eigen::MatrixXd truncation, error, centred;
  Eigen::MatrixXd variation;  // of M - mean_H M: J G J with J the centring over nodes
  Eigen::VectorXd node_error2;
};

HeldOutGrams held_out_grams(const TransferReduction& r, const HeldOutTruth& truth,
                            const Eigen::Ref<const MatrixXfR>& served) {
  if (served.rows() != truth.fields.rows() || served.cols() != r.rank()) {
    throw std::invalid_argument(fmt::format("truth_error: expected served q_a of {} x {}, got {} x {}",
                                            truth.fields.rows(), r.rank(), served.rows(), served.cols()));
  }
  const Eigen::MatrixXd U = r.U_a.cast<double>();
  const Eigen::VectorXd mean = r.mean_transfer.cast<double>();
  const Eigen::Index H = truth.fields.rows();
  Eigen::MatrixXf T(mean.size(), H);
  Eigen::MatrixXd P(r.rank(), H), S(r.rank(), H);
  HeldOutGrams g;
  g.node_error2.resize(H);
  for (Eigen::Index h = 0; h < H; ++h) {
    const Eigen::VectorXd m = truth.fields.row(h).transpose().cast<double>();
    const Eigen::VectorXd d = m - mean;
    P.col(h) = U.transpose() * d;  // the best coordinates rank r_a has
    S.col(h) = served.row(h).transpose().cast<double>();
    const Eigen::VectorXd t = d - U * P.col(h);
    T.col(h) = t.cast<float>();
    g.truth2 += m.squaredNorm();
    g.centred2 += d.squaredNorm();
    g.truncation2 += t.squaredNorm();
    g.interpolation2 += (P.col(h) - S.col(h)).squaredNorm();
    g.node_error2[h] = (d - U * S.col(h)).squaredNorm();
    g.total2 += g.node_error2[h];
  }
  g.truncation = gram(T);
  const Eigen::MatrixXd D = P - S;
  g.error = g.truncation + D.transpose() * D;
  g.centred = g.truncation + P.transpose() * P;
  if (H > 0) {
    g.variation = centred_over_nodes(g.centred);
    g.variation2 = std::max(0.0, g.variation.trace());
  }
  return g;
}

// The relative l2 figures over the nodes `pick` (repeats allowed): |E|_2 / |M - M-bar|_2
// from the Gram matrices' rows and columns `pick`; false when nothing varies there.
bool l2_figures(const HeldOutGrams& g, const std::vector<Eigen::Index>& pick, double& total,
                double& truncation) {
  const double centred = largest_eigenvalue(g.centred(pick, pick));
  if (!(centred > 0)) return false;  // 0 only when the float residuals underflow
  total = std::sqrt(largest_eigenvalue(g.error(pick, pick)) / centred);
  truncation = std::sqrt(largest_eigenvalue(g.truncation(pick, pick)) / centred);
  return true;
}

// sigma_{rank+1} / sigma_1 of X from its Gram matrix X^T X: the least relative
// l2 error of any rank-`rank` approximation of X (Eckart-Young); 0 when X has
// no more than `rank` columns or does not vary.
double rank_floor(const Eigen::MatrixXd& gram, int rank) {
  if (gram.rows() <= rank) return 0;
  const Eigen::VectorXd lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(gram, Eigen::EigenvaluesOnly)
                                     .eigenvalues();  // ascending
  const double first = lambda[lambda.size() - 1];
  if (!(first > 0)) return 0;
  return std::sqrt(std::max(0.0, lambda[lambda.size() - 1 - rank]) / first);
}

double percentile(std::vector<double> v, double p) {
  const auto at = v.begin() + static_cast<std::ptrdiff_t>(std::lround(p * static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), at, v.end());
  return *at;
}

}  // namespace

TruthError truth_error(const TransferReduction& r, const HeldOutTruth& truth,
                       const Eigen::Ref<const MatrixXfR>& served) {
  const HeldOutGrams g = held_out_grams(r, truth, served);
  TruthError e;
  e.node_error2 = g.node_error2;
  if (g.centred2 > 0) {
    e.total = std::sqrt(g.total2 / g.centred2);
    e.truncation = std::sqrt(g.truncation2 / g.centred2);
    e.interpolation = std::sqrt(g.interpolation2 / g.centred2);
    std::vector<Eigen::Index> all(static_cast<size_t>(truth.fields.rows()));
    std::iota(all.begin(), all.end(), Eigen::Index{0});
    l2_figures(g, all, e.l2_total, e.l2_truncation);
    e.l2_floor = rank_floor(g.centred, r.rank());
  }
  if (g.variation2 > kNoVariation * g.centred2) {
    e.of_variation = std::sqrt(g.total2 / g.variation2);
    const double variation = largest_eigenvalue(g.variation);
    if (variation > 0) e.l2_of_variation = std::sqrt(largest_eigenvalue(g.error) / variation);
    e.l2_floor_of_variation = rank_floor(g.variation, r.rank());
  }
  if (g.truth2 > 0) e.of_transfer = std::sqrt(g.total2 / g.truth2);
  return e;
}

PairedGain paired_gain(const Eigen::VectorXd& baseline, const Eigen::VectorXd& candidate) {
  if (baseline.size() != candidate.size())
    throw std::invalid_argument(fmt::format("paired_gain: {} baseline errors for {} candidate errors",
                                            baseline.size(), candidate.size()));
  const auto n = static_cast<double>(baseline.size());
  const double sum = baseline.sum();
  if (n < 2 || !(sum > 0)) return {0, std::numeric_limits<double>::infinity()};
  const Eigen::VectorXd less = baseline - candidate;  // per node: what the candidate saves
  const double variance = (less.array() - less.mean()).square().sum() / (n - 1);
  // Student's t, not 2: a picking half of a few nodes estimates the spread badly.
  const double t = boost::math::quantile(boost::math::students_t(n - 1), 0.975);
  return {less.sum() / sum, t * std::sqrt(variance * n) / sum};
}

TruthErrorSpread truth_error_spread(const TransferReduction& r, const HeldOutTruth& truth,
                                    const Eigen::Ref<const MatrixXfR>& served, int draws,
                                    std::uint64_t seed) {
  if (draws < 1)
    throw std::invalid_argument(fmt::format("truth_error_spread: expected draws >= 1, got {}", draws));
  const HeldOutGrams g = held_out_grams(r, truth, served);
  const auto H = static_cast<std::uint64_t>(truth.fields.rows());
  TruthErrorSpread spread;
  if (H == 0) return spread;
  std::mt19937_64 rng(seed);
  std::vector<double> totals, truncations, of_variation;
  std::vector<Eigen::Index> pick(H);
  for (int d = 0; d < draws; ++d) {
    // Modulo draws, no library distribution: every platform resamples alike.
    for (auto& node : pick) node = static_cast<Eigen::Index>(rng() % H);
    double total = 0, truncation = 0;
    if (!l2_figures(g, pick, total, truncation)) continue;
    totals.push_back(total);
    truncations.push_back(truncation);
    const Eigen::MatrixXd centred = g.centred(pick, pick);
    const double variation = largest_eigenvalue(centred_over_nodes(centred));
    if (variation > kNoVariation * largest_eigenvalue(centred))
      of_variation.push_back(std::sqrt(largest_eigenvalue(g.error(pick, pick)) / variation));
  }
  if (totals.empty()) return spread;
  spread.l2_total = {percentile(totals, 0.1), percentile(totals, 0.9)};
  spread.l2_truncation = {percentile(truncations, 0.1), percentile(truncations, 0.9)};
  if (!of_variation.empty())
    spread.l2_of_variation = std::array{percentile(of_variation, 0.1), percentile(of_variation, 0.9)};
  return spread;
}

namespace {
// q_a = U_a^T (M - M-bar) at every node, in double like the truth's own
// coordinates (held_out_grams): the served basis's best coordinates.
MatrixXfR projections(const TransferReduction& r, const HeldOutTruth& truth) {
  const Eigen::MatrixXd U = r.U_a.cast<double>();
  const Eigen::RowVectorXd mean = r.mean_transfer.transpose().cast<double>();
  MatrixXfR out(truth.fields.rows(), r.rank());
  for (Eigen::Index h = 0; h < truth.fields.rows(); ++h)
    out.row(h) = ((truth.fields.row(h).cast<double>() - mean) * U).cast<float>();
  return out;
}
}  // namespace

std::optional<BasisComparison> compare_with_drawn_basis(const TransferReduction& reduction,
                                                        const HeldOutTruth& picking,
                                                        const HeldOutTruth& test) {
  for (const HeldOutTruth* h : {&picking, &test}) {
    if (h->fields.rows() > 0 && h->fields.cols() != reduction.mean_transfer.size()) {
      throw std::invalid_argument(
          fmt::format("compare_with_drawn_basis: expected fields of width {} (48S), got {}",
                      reduction.mean_transfer.size(), h->fields.cols()));
    }
  }
  const int rank = reduction.rank();
  if (test.nodes.size() < 2 || rank == 0 || picking.fields.rows() <= rank) return std::nullopt;
  const TransferReduction drawn = reduce_transfer(picking.fields, {.eps_a = 0, .rank = rank});
  if (drawn.rank() < rank) return std::nullopt;
  BasisComparison c;
  c.served = truth_error(reduction, test, projections(reduction, test));
  c.drawn = truth_error(drawn, test, projections(drawn, test));
  c.drawn_fields = static_cast<int>(picking.fields.rows());
  c.drawn_gain = paired_gain(c.served.node_error2, c.drawn.node_error2);
  return c;
}

// The least rank whose truncation alone at the picking nodes (relative l2)
// is at most `target`, by the paper's equal-weight SVD (its right vectors
// suffice: held_out_truncation_curve forms the directions itself); all the
// resolved directions when none is.
HeldOutRankChoice rank_for_held_out_target(const Eigen::Ref<const MatrixXfR>& fields,
                                           const HeldOutTruth& picking, double target) {
  if (picking.nodes.empty()) {
    throw std::invalid_argument(
        "fit_appearance_model: held_out_target needs picking nodes to measure it at (--held-out >= 2)");
  }
  const TransferReduction probe = reduce_transfer(fields, {.eps_a = 0, .rank = 1});
  const VectorXf curve = held_out_truncation_curve(fields, probe, picking.fields);
  HeldOutRankChoice c{target, static_cast<int>(curve.size()), curve.size() ? curve[curve.size() - 1] : 0.0,
                      false, static_cast<int>(picking.nodes.size())};
  for (Eigen::Index i = 0; i < curve.size(); ++i) {
    if (curve[i] <= target) {
      c = {target, static_cast<int>(i + 1), curve[i], true, c.picking_nodes};
      break;
    }
  }
  return c;
}

core::HeldOutFigures held_out_figures(const TruthError& e, const HeldOutTruth& test,
                                      const TransferReduction& reduction,
                                      const std::optional<TruthErrorSpread>& spread) {
  const auto single = [](double v) { return static_cast<float>(v); };
  core::HeldOutFigures h;
  h.nodes = test.nodes;
  h.total = single(e.total);
  h.truncation = single(e.truncation);
  h.interpolation = single(e.interpolation);
  h.of_transfer = single(e.of_transfer);
  h.l2_total = single(e.l2_total);
  h.l2_truncation = single(e.l2_truncation);
  // The clusters' own truncation over as many columns as the reported half:
  // the figure its l2 truncation compares with (transfer_reduction.h).
  h.clusters_l2_truncation = single(cluster_truncation_l2(reduction, static_cast<int>(test.nodes.size())));
  h.l2_floor = single(e.l2_floor);
  // One node does not vary about its own mean: its figures would read 0.
  if (test.nodes.size() >= 2) {
    h.of_variation = single(e.of_variation);
    h.l2_of_variation = single(e.l2_of_variation);
    h.l2_floor_of_variation = single(e.l2_floor_of_variation);
  }
  if (!spread) return h;
  h.l2_total_spread = core::Percentiles{single(spread->l2_total[0]), single(spread->l2_total[1])};
  h.l2_truncation_spread =
      core::Percentiles{single(spread->l2_truncation[0]), single(spread->l2_truncation[1])};
  if (const auto& own = spread->l2_of_variation)
    h.l2_of_variation_spread = core::Percentiles{single((*own)[0]), single((*own)[1])};
  return h;
}

}  // namespace phasecast::precompute
