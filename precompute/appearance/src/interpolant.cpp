#include "phasecast/precompute/appearance/interpolant.h"

#include <fmt/format.h>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

// Inverse-square-distance weights of the k nearest of `centers` (rows other
// than `skip`) to q; a query on a centre takes that centre's sample.
Eigen::RowVectorXd knn_at(const MatrixXfR& centers, const MatrixXfR& samples, int k,
                          const Eigen::Ref<const Eigen::RowVectorXf>& q, Eigen::Index skip = -1) {
  std::vector<std::pair<double, Eigen::Index>> d;
  for (Eigen::Index j = 0; j < centers.rows(); ++j)
    if (j != skip) d.emplace_back((centers.row(j) - q).cast<double>().squaredNorm(), j);
  const auto n = std::min<size_t>(static_cast<size_t>(k), d.size());
  std::partial_sort(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(n), d.end());
  Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(samples.cols());
  if (n > 0 && d[0].first == 0) return samples.row(d[0].second).cast<double>();
  double total = 0;
  for (size_t i = 0; i < n; ++i) {
    const double w = 1 / d[i].first;
    sum += w * samples.row(d[i].second).cast<double>();
    total += w;
  }
  return total > 0 ? Eigen::RowVectorXd(sum / total) : sum;
}

double knn_leave_one_out(const MatrixXfR& centers, const MatrixXfR& samples, int k) {
  double err2 = 0, norm2 = 0;
  for (Eigen::Index j = 0; j < centers.rows(); ++j) {
    err2 += (knn_at(centers, samples, k, centers.row(j), j) - samples.row(j).cast<double>()).squaredNorm();
    norm2 += samples.row(j).cast<double>().squaredNorm();
  }
  return norm2 > 0 ? std::sqrt(err2 / norm2) : 0;
}

// [1 q] for every row q.
Eigen::MatrixXd with_ones(const Eigen::Ref<const MatrixXfR>& q) {
  Eigen::MatrixXd X(q.rows(), q.cols() + 1);
  X.col(0).setOnes();
  X.rightCols(q.cols()) = q.cast<double>();
  return X;
}

// The affine map [1 q] M of the rows of X = [1 q] to Y by least squares with
// a ridge on the slope of `ridge` times the samples' mean squared spread per
// coordinate. Fitted about the means, so the intercept is never shrunk;
// without a ridge, where the samples leave the slope open (fewer than
// 1 + r_u) the least-norm one is taken: one sample gives a constant.
Eigen::MatrixXd fit_affine(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y, double ridge) {
  const Eigen::Index r_u = X.cols() - 1;
  const Eigen::RowVectorXd x_mean = X.colwise().mean(), y_mean = Y.colwise().mean();
  const Eigen::MatrixXd dX = X.rightCols(r_u).rowwise() - x_mean.tail(r_u);
  const Eigen::MatrixXd dY = Y.rowwise() - y_mean;
  const double spread = r_u > 0 ? dX.squaredNorm() / static_cast<double>(r_u) : 0.0;
  Eigen::MatrixXd map(X.cols(), Y.cols());
  if (ridge > 0 && spread > 0) {
    Eigen::MatrixXd gram = dX.transpose() * dX;
    gram.diagonal().array() += ridge * spread;
    map.bottomRows(r_u) = gram.ldlt().solve(dX.transpose() * dY);
  } else {
    map.bottomRows(r_u) = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(dX).solve(dY);
  }
  map.row(0) = y_mean - x_mean.tail(r_u) * map.bottomRows(r_u);
  return map;
}

void check_samples(const char* name, const Eigen::Ref<const MatrixXfR>& centers,
                   const Eigen::Ref<const MatrixXfR>& samples) {
  if (centers.rows() == 0 || samples.rows() != centers.rows()) {
    throw std::invalid_argument(
        fmt::format("{}: expected one sample per centre ({}), got {}", name, centers.rows(), samples.rows()));
  }
}

// The points where affine-knn looks for neighbours: q_u, or its image under
// slope_metric of `map`'s slope.
MatrixXfR neighbour_space(const Eigen::Ref<const MatrixXfR>& q, const Eigen::MatrixXd& map,
                          NeighbourMetric metric) {
  if (metric == NeighbourMetric::state) return q;
  const Eigen::MatrixXd W = slope_metric(map.bottomRows(map.rows() - 1));
  MatrixXfR out(q.rows(), W.cols());
  // Row by row, so that a query equal to a centre lands exactly on it (knn_at).
  for (Eigen::Index i = 0; i < q.rows(); ++i) out.row(i) = (q.row(i).cast<double>() * W).cast<float>();
  return out;
}

// Leave-one-out of affine-knn for every ridge and k of the grids at once
// (err2[ridge][k]): each sample is left out of the map's fit, of the knn
// and of the metric.
std::vector<std::vector<double>> affine_knn_leave_one_out(const Eigen::Ref<const MatrixXfR>& centers,
                                                          const Eigen::Ref<const MatrixXfR>& samples,
                                                          const std::vector<int>& ks,
                                                          NeighbourMetric metric) {
  const Eigen::Index Na = centers.rows();
  const Eigen::MatrixXd X = with_ones(centers), Y = samples.cast<double>();
  std::vector<std::vector<double>> err2(std::size(kAffineRidges), std::vector<double>(ks.size(), 0.0));
  for (Eigen::Index j = 0; j < Na; ++j) {
    Eigen::MatrixXd Xo(Na - 1, X.cols()), Yo(Na - 1, Y.cols());
    for (Eigen::Index i = 0, o = 0; i < Na; ++i)
      if (i != j) Xo.row(o) = X.row(i), Yo.row(o++) = Y.row(i);
    for (size_t r = 0; r < err2.size(); ++r) {
      const Eigen::MatrixXd map = fit_affine(Xo, Yo, kAffineRidges[r]);
      const MatrixXfR rest = (Y - X * map).cast<float>();  // row j unused: knn skips it
      const MatrixXfR points = neighbour_space(centers, map, metric);
      for (size_t m = 0; m < ks.size(); ++m) {
        const Eigen::RowVectorXd guess = X.row(j) * map + knn_at(points, rest, ks[m], points.row(j), j);
        err2[r][m] += (guess - Y.row(j)).squaredNorm();
      }
    }
  }
  return err2;
}

// The k of kKnnNeighbours that leave-one-out may try with `Na` samples.
std::vector<int> neighbour_grid(Eigen::Index Na) {
  std::vector<int> ks;
  for (int k : kKnnNeighbours)
    if (k <= std::max<Eigen::Index>(1, Na - 1)) ks.push_back(k);
  return ks;
}

}  // namespace

const char* interpolant_name(InterpolantKind kind) {
  switch (kind) {
    case InterpolantKind::knn:
      return "knn";
    case InterpolantKind::affine_knn:
      return "affine-knn";
    case InterpolantKind::affine_knn_slope:
      return "affine-knn-slope";
    case InterpolantKind::nrbf:
      break;
  }
  return "nrbf";
}

Interpolant tune_nrbf(const Eigen::Ref<const MatrixXfR>& q_u, const std::vector<std::int32_t>& labels,
                      const Eigen::Ref<const MatrixXfR>& centers, const Eigen::Ref<const MatrixXfR>& samples,
                      const std::function<void(const char*, long, long)>& progress) {
  Interpolant best;
  best.leave_one_out = std::numeric_limits<double>::infinity();
  const bool single = centers.rows() < 2;
  const auto grid = static_cast<long>(std::size(kNrbfWidthScales) * std::size(kNrbfRegularizations));
  long done = 0;
  if (progress && !single) progress("appearance nrbf tuning", 0, grid);
  for (float scale : kNrbfWidthScales) {
    const VectorXf widths = nrbf_widths(q_u, labels, centers, scale);
    for (float lambda : kNrbfRegularizations) {
      const double loo = single ? 0.0 : nrbf_leave_one_out(centers, widths, samples, lambda).relative;
      if (progress && !single) progress("appearance nrbf tuning", ++done, grid);
      if (!(loo < best.leave_one_out)) continue;
      best.nrbf = fit_nrbf(centers, widths, samples, lambda);
      best.width_scale = scale;
      best.leave_one_out = loo;
      if (single) return best;
    }
  }
  return best;
}

Interpolant tune_knn(const Eigen::Ref<const MatrixXfR>& centers, const Eigen::Ref<const MatrixXfR>& samples) {
  check_samples("knn", centers, samples);
  Interpolant best;
  best.kind = InterpolantKind::knn;
  best.nrbf.centers = centers;
  best.nrbf.weights = samples;
  best.nrbf.widths = VectorXf::Ones(centers.rows());
  best.nrbf.regularization = 0;
  best.leave_one_out = std::numeric_limits<double>::infinity();
  for (int k : neighbour_grid(centers.rows())) {
    const double loo = centers.rows() < 2 ? 0.0 : knn_leave_one_out(centers, samples, k);
    if (loo < best.leave_one_out) {
      best.neighbours = k;
      best.leave_one_out = loo;
    }
  }
  return best;
}

bool has_affine_map(InterpolantKind kind) {
  return kind == InterpolantKind::affine_knn || kind == InterpolantKind::affine_knn_slope;
}

Eigen::MatrixXd slope_metric(const Eigen::Ref<const Eigen::MatrixXd>& slope) {
  const Eigen::Index r_u = slope.rows();
  const double norm2 = slope.squaredNorm();
  const double eps =
      norm2 > 0 ? kSlopeIsotropy * norm2 / static_cast<double>(std::max<Eigen::Index>(r_u, 1)) : 1.0;
  Eigen::MatrixXd W(r_u, slope.cols() + r_u);
  W << slope, std::sqrt(eps) * Eigen::MatrixXd::Identity(r_u, r_u);
  return W;
}

Interpolant tune_affine_knn(const Eigen::Ref<const MatrixXfR>& centers,
                            const Eigen::Ref<const MatrixXfR>& samples, NeighbourMetric metric) {
  check_samples("affine-knn", centers, samples);
  const Eigen::MatrixXd X = with_ones(centers), Y = samples.cast<double>();
  const std::vector<int> ks = neighbour_grid(centers.rows());
  size_t ridge = 0, k = 0;  // grid indices; one sample: no ridge, the first k
  double loo = 0;
  if (centers.rows() >= 2) {
    const auto err2 = affine_knn_leave_one_out(centers, samples, ks, metric);
    double least = std::numeric_limits<double>::infinity();
    for (size_t r = 0; r < err2.size(); ++r)
      for (size_t m = 0; m < ks.size(); ++m)
        if (err2[r][m] < least) least = err2[r][m], ridge = r, k = m;  // ties: smaller ridge, then k
    const double norm2 = Y.squaredNorm();
    loo = norm2 > 0 ? std::sqrt(least / norm2) : 0;
  }
  Interpolant best;
  best.kind =
      metric == NeighbourMetric::slope ? InterpolantKind::affine_knn_slope : InterpolantKind::affine_knn;
  best.affine = fit_affine(X, Y, kAffineRidges[ridge]).cast<float>();
  best.nrbf.centers = centers;
  // Against the stored (float) map, so that map and remainders give back each sample.
  best.nrbf.weights = (Y - X * best.affine.cast<double>()).cast<float>();
  best.nrbf.widths = VectorXf::Ones(centers.rows());
  best.nrbf.regularization = kAffineRidges[ridge];
  best.neighbours = ks[k];
  best.leave_one_out = loo;
  return best;
}

MatrixXfR evaluate_interpolant(const Interpolant& f, const Eigen::Ref<const MatrixXfR>& q) {
  if (f.kind == InterpolantKind::nrbf) return evaluate_nrbf(f.nrbf, q);
  const Eigen::Index r_u = f.nrbf.centers.cols(), r_a = f.nrbf.weights.cols();
  if (q.cols() != r_u) {
    throw std::invalid_argument(fmt::format("{}: queries must have {} columns (r_u), got {}",
                                            interpolant_name(f.kind), r_u, q.cols()));
  }
  const bool affine = has_affine_map(f.kind);
  if (affine && (f.affine.rows() != 1 + r_u || f.affine.cols() != r_a)) {
    throw std::invalid_argument(fmt::format("{}: expected a {} x {} affine map (1 + r_u, r_a), got {} x {}",
                                            interpolant_name(f.kind), 1 + r_u, r_a, f.affine.rows(),
                                            f.affine.cols()));
  }
  const Eigen::MatrixXd map = f.affine.cast<double>();
  const Eigen::MatrixXd trend =
      affine ? Eigen::MatrixXd(with_ones(q) * map) : Eigen::MatrixXd::Zero(q.rows(), r_a);
  const auto metric =
      f.kind == InterpolantKind::affine_knn_slope ? NeighbourMetric::slope : NeighbourMetric::state;
  const MatrixXfR points = neighbour_space(f.nrbf.centers, map, metric);
  const MatrixXfR queries = neighbour_space(q, map, metric);
  MatrixXfR out(q.rows(), r_a);
  for (Eigen::Index i = 0; i < q.rows(); ++i)
    out.row(i) = (trend.row(i) + knn_at(points, f.nrbf.weights, f.neighbours, queries.row(i))).cast<float>();
  return out;
}

}  // namespace phasecast::precompute
