#include "phasecast/precompute/appearance/transfer_appearance.h"

#include "largest_eigenvalue.h"

#include <fmt/format.h>
#include <Eigen/Eigenvalues>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <random>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

MatrixXfR cluster_centers(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters) {
  const auto Na = static_cast<Eigen::Index>(clusters.representatives.size());
  MatrixXfR centers(Na, q_u.cols());
  for (Eigen::Index j = 0; j < Na; ++j) {
    const auto node = clusters.representatives[static_cast<size_t>(j)];
    if (node < 0 || node >= q_u.rows()) {
      throw std::invalid_argument(fmt::format(
          "fit_appearance_model: representative {} is node {}, expected 0..{}", j, node, q_u.rows() - 1));
    }
    centers.row(j) = q_u.row(node);
  }
  return centers;
}

void check_held_out(const HeldOutTruth& h, Eigen::Index N, Eigen::Index width) {
  if (static_cast<Eigen::Index>(h.nodes.size()) != h.fields.rows() ||
      (h.fields.rows() && h.fields.cols() != width)) {
    throw std::invalid_argument(
        fmt::format("fit_appearance_model: held-out truth must be {} x {}, got {} x {}", h.nodes.size(),
                    width, h.fields.rows(), h.fields.cols()));
  }
  for (auto n : h.nodes) {
    if (n < 0 || n >= N)
      throw std::invalid_argument(
          fmt::format("fit_appearance_model: held-out node {} is not in 0..{}", n, N - 1));
  }
}

// Rows [begin, begin + count) of the held-out truth.
HeldOutTruth part(const HeldOutTruth& h, size_t begin, size_t count) {
  HeldOutTruth out;
  out.nodes.assign(h.nodes.begin() + static_cast<std::ptrdiff_t>(begin),
                   h.nodes.begin() + static_cast<std::ptrdiff_t>(begin + count));
  out.fields = h.fields.middleRows(static_cast<Eigen::Index>(begin), static_cast<Eigen::Index>(count));
  return out;
}

MatrixXfR rows_of(const Eigen::Ref<const MatrixXfR>& q, const std::vector<std::int32_t>& nodes) {
  MatrixXfR out(static_cast<Eigen::Index>(nodes.size()), q.cols());
  for (size_t i = 0; i < nodes.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = q.row(nodes[i]);
  return out;
}

using WeightedReduction = std::pair<TransferWeighting, TransferReduction>;

// The reductions `o.weighting` allows (§4.2), equal weights first. The paper's
// A_a sets r_a for all of them, so that candidates compare at the one cost a
// client pays; `spectrum` and `curve` receive its singular values and error
// curve (the paper's relErr, Fig. 12). best tries cluster sizes only with
// held-out truth to judge by, and only where they differ; a weighted
// reduction that resolves fewer than r_a directions is not tried.
std::vector<WeightedReduction> reductions(const Eigen::Ref<const MatrixXfR>& fields,
                                          const KMeansResult& clusters, const AppearanceOptions& o,
                                          bool judged, VectorXf& spectrum, VectorXf& curve) {
  TransferReduction equal = reduce_transfer(fields, o.reduction);
  spectrum = equal.singular_values;
  curve = equal.rel_error;
  const int rank = equal.rank();
  std::vector<WeightedReduction> out;
  if (o.weighting != WeightingChoice::cluster_size)
    out.emplace_back(TransferWeighting::equal, std::move(equal));
  const Eigen::VectorXd weights = cluster_size_weights(clusters);
  const bool differ = weights.maxCoeff() - weights.minCoeff() > 1e-9;
  const bool wanted = o.weighting == WeightingChoice::cluster_size ||
                      (o.weighting == WeightingChoice::best && judged && differ);
  if (wanted && rank > 0) {
    TransferReduction weighted = reduce_transfer(fields, {.eps_a = o.reduction.eps_a, .rank = rank}, weights);
    if (weighted.rank() == rank) out.emplace_back(TransferWeighting::cluster_size, std::move(weighted));
  }
  if (out.empty()) out.emplace_back(TransferWeighting::equal, std::move(equal));  // nothing to weight
  return out;
}

std::vector<Interpolant> candidates(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters,
                                    const MatrixXfR& centers, const MatrixXfR& samples,
                                    InterpolantChoice choice,
                                    const std::function<void(const char*, long, long)>& progress) {
  std::vector<Interpolant> out;
  const bool all = choice == InterpolantChoice::best;
  if (all || choice == InterpolantChoice::nrbf)
    out.push_back(tune_nrbf(q_u, clusters.labels, centers, samples, progress));
  if (all || choice == InterpolantChoice::knn) out.push_back(tune_knn(centers, samples));
  if (all || choice == InterpolantChoice::affine_knn) out.push_back(tune_affine_knn(centers, samples));
  if (all || choice == InterpolantChoice::affine_knn_slope)
    out.push_back(tune_affine_knn(centers, samples, NeighbourMetric::slope));
  return out;
}

// nrbf: width scale, lambda; knn: k; affine-knn(-slope): k, then the affine map row by row.
VectorXf interpolant_parameters(const Interpolant& f) {
  if (f.kind == InterpolantKind::nrbf)
    return (VectorXf(2) << f.width_scale, f.nrbf.regularization).finished();
  VectorXf v(1 + (has_affine_map(f.kind) ? f.affine.size() : 0));
  v[0] = static_cast<float>(f.neighbours);
  v.tail(v.size() - 1) = Eigen::Map<const VectorXf>(f.affine.data(), f.affine.size());
  return v;
}

void store_choice(core::Appearance& a, const CandidateReport& c, const HeldOutTruth& test,
                  const TransferReduction& reduction, const std::optional<TruthErrorSpread>& spread) {
  const Interpolant& f = c.interpolant;
  a.interpolant = interpolant_name(f.kind);
  a.interpolant_parameters = interpolant_parameters(f);
  a.nrbf_centers = f.nrbf.centers;
  a.nrbf_weights = f.nrbf.weights;
  a.nrbf_widths = f.nrbf.widths;
  a.nrbf_regularization = f.nrbf.regularization;
  a.transfer_weighting = weighting_name(c.weighting);
  if (test.nodes.empty()) return;
  a.held_out_nodes = test.nodes;
  // The clusters' own truncation over as many columns as the reported half:
  // the figure its l2 truncation compares with (transfer_reduction.h).
  const double clusters_l2 = cluster_truncation_l2(reduction, static_cast<int>(test.nodes.size()));
  const TruthError& e = c.test;
  a.held_out_error.resize(11);
  a.held_out_error << static_cast<float>(e.total), static_cast<float>(e.truncation),
      static_cast<float>(e.interpolation), static_cast<float>(e.of_transfer), static_cast<float>(e.l2_total),
      static_cast<float>(e.l2_truncation), static_cast<float>(clusters_l2), static_cast<float>(e.l2_floor),
      static_cast<float>(e.of_variation), static_cast<float>(e.l2_of_variation),
      static_cast<float>(e.l2_floor_of_variation);
  // One node does not vary about its own mean: its figures would read 0.
  if (test.nodes.size() < 2) a.held_out_error.conservativeResize(8);
  if (!spread) return;
  a.held_out_spread.resize(4);
  a.held_out_spread << static_cast<float>(spread->l2_total[0]), static_cast<float>(spread->l2_total[1]),
      static_cast<float>(spread->l2_truncation[0]), static_cast<float>(spread->l2_truncation[1]);
  if (const auto& own = spread->l2_of_variation) {
    a.held_out_spread.conservativeResize(6);
    a.held_out_spread.tail(2) << static_cast<float>((*own)[0]), static_cast<float>((*own)[1]);
  }
}

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

// Equal weights are the paper's (§4.2): the best cluster-size candidate goes
// first only where its paired gain over the best equal one on the picking
// half is beyond its noise. A picking half of 20-50 nodes reads differences
// of a few percent either way (on one draw the default plant's picked
// cluster sizes 0.4 points better and its reported half read them 1.1
// points worse). `ranked` is sorted by the picking half.
std::optional<PairedGain> keep_equal_within_noise(std::vector<CandidateReport>& ranked) {
  const auto first_of = [&](TransferWeighting w) {
    return std::find_if(ranked.begin(), ranked.end(), [&](const auto& c) { return c.weighting == w; });
  };
  const auto equal = first_of(TransferWeighting::equal), weighted = first_of(TransferWeighting::cluster_size);
  if (equal == ranked.end() || weighted == ranked.end() || equal->selection.node_error2.size() == 0)
    return std::nullopt;
  const PairedGain gain = paired_gain(equal->selection.node_error2, weighted->selection.node_error2);
  if (weighted == ranked.begin() && !gain.beyond_noise()) std::rotate(ranked.begin(), equal, equal + 1);
  return gain;
}

}  // namespace

const char* weighting_name(TransferWeighting weighting) {
  return weighting == TransferWeighting::cluster_size ? "cluster size" : "equal";
}

Eigen::VectorXd cluster_size_weights(const KMeansResult& clusters) {
  const auto Na = static_cast<Eigen::Index>(clusters.representatives.size());
  Eigen::VectorXd count = Eigen::VectorXd::Zero(Na);
  for (const auto label : clusters.labels) {
    if (label < 0 || label >= Na)
      throw std::invalid_argument(
          fmt::format("cluster_size_weights: label {} is not a cluster in 0..{}", label, Na - 1));
    count[label] += 1;
  }
  count = count.cwiseMax(1.0);
  return count * (static_cast<double>(Na) / count.sum());
}

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

namespace {

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

}  // namespace

AppearanceModel fit_appearance_model(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters,
                                     const Eigen::Ref<const MatrixXfR>& fields,
                                     const AppearanceOptions& options, const HeldOutTruth& held_out) {
  const auto Na = static_cast<Eigen::Index>(clusters.representatives.size());
  if (Na == 0 || fields.rows() != Na) {
    throw std::invalid_argument(fmt::format(
        "fit_appearance_model: expected one transfer field per cluster ({}), got {}", Na, fields.rows()));
  }
  if (static_cast<Eigen::Index>(clusters.labels.size()) != q_u.rows()) {
    throw std::invalid_argument(fmt::format("fit_appearance_model: clusters label {} nodes but q_u has {}",
                                            clusters.labels.size(), q_u.rows()));
  }
  check_held_out(held_out, q_u.rows(), fields.cols());
  const MatrixXfR centers = cluster_centers(q_u, clusters);

  // Candidates tuned on the samples; the first half of the held-out nodes
  // picks one, the second half measures it (the choice never sees it).
  const size_t H = held_out.nodes.size(), selection_size = held_out_picking_count(H);
  const HeldOutTruth selection = part(held_out, 0, selection_size);
  const HeldOutTruth test = part(held_out, selection_size, H - selection_size);
  AppearanceModel m;
  core::Appearance& a = m.appearance;
  AppearanceOptions o = options;
  if (o.held_out_target > 0) {
    m.rank_choice = rank_for_held_out_target(fields, selection, o.held_out_target);
    o.reduction = {.eps_a = 0, .rank = m.rank_choice->rank};
  }
  const std::vector<WeightedReduction> tried =
      reductions(fields, clusters, o, !selection.nodes.empty(), a.singular_values, a.rel_error);
  for (const auto& [w, reduction] : tried) {
    const MatrixXfR samples = reduction.Q_a.transpose();  // q_a^j at centre j
    for (auto& f : candidates(q_u, clusters, centers, samples, o.interpolant, o.progress)) {
      CandidateReport c{std::move(f), w, {}, {}};
      if (!selection.nodes.empty())
        c.selection = truth_error(reduction, selection,
                                  evaluate_interpolant(c.interpolant, rows_of(q_u, selection.nodes)));
      if (!test.nodes.empty())
        c.test = truth_error(reduction, test, evaluate_interpolant(c.interpolant, rows_of(q_u, test.nodes)));
      m.candidates.push_back(std::move(c));
    }
  }
  // Without held-out truth only one weighting is tried, so leave-one-out
  // (relative to that reduction's samples) compares like with like.
  const auto score = [&](const CandidateReport& c) {
    return selection.nodes.empty() ? c.interpolant.leave_one_out : c.selection.of_transfer;
  };
  std::stable_sort(m.candidates.begin(), m.candidates.end(),
                   [&](const CandidateReport& x, const CandidateReport& y) { return score(x) < score(y); });
  if (o.weighting == WeightingChoice::best) m.weighting_gain = keep_equal_within_noise(m.candidates);
  const CandidateReport& chosen = m.candidates.front();
  const TransferReduction& reduction = std::find_if(tried.begin(), tried.end(), [&](const auto& r) {
                                         return r.first == chosen.weighting;
                                       })->second;
  m.q_a = evaluate_interpolant(chosen.interpolant, q_u);  // §4.3: q_a(q_u) at every state node

  a.mean_transfer = reduction.mean_transfer;
  a.U_a = reduction.U_a;
  a.cluster_nodes = clusters.representatives;
  // How much the reported figures owe to which nodes were drawn; one node
  // resamples only to itself, which would read as no spread at all.
  std::optional<TruthErrorSpread> spread;
  if (test.nodes.size() >= 2)
    spread = truth_error_spread(reduction, test,
                                evaluate_interpolant(chosen.interpolant, rows_of(q_u, test.nodes)));
  store_choice(a, chosen, test, reduction, spread);
  a.held_out_truncation_curve = held_out_truncation_curve(fields, reduction, test.fields);
  m.basis_comparison = compare_with_drawn_basis(reduction, selection, test);
  return m;
}

}  // namespace phasecast::precompute
