#include "phasecast/precompute/appearance/interpolant.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
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

}  // namespace

const char* interpolant_name(InterpolantKind kind) {
  return kind == InterpolantKind::knn ? "knn" : "nrbf";
}

Interpolant tune_nrbf(const Eigen::Ref<const MatrixXfR>& q_u, const std::vector<std::int32_t>& labels,
                      const Eigen::Ref<const MatrixXfR>& centers,
                      const Eigen::Ref<const MatrixXfR>& samples) {
  Interpolant best;
  best.leave_one_out = std::numeric_limits<double>::infinity();
  const bool single = centers.rows() < 2;
  for (float scale : kNrbfWidthScales) {
    const VectorXf widths = nrbf_widths(q_u, labels, centers, scale);
    for (float lambda : kNrbfRegularizations) {
      const double loo = single ? 0.0 : nrbf_leave_one_out(centers, widths, samples, lambda).relative;
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
  if (centers.rows() == 0 || samples.rows() != centers.rows()) {
    throw std::invalid_argument(
        fmt::format("knn: expected one sample per centre ({}), got {}", centers.rows(), samples.rows()));
  }
  Interpolant best;
  best.kind = InterpolantKind::knn;
  best.nrbf.centers = centers;
  best.nrbf.weights = samples;
  best.nrbf.widths = VectorXf::Ones(centers.rows());
  best.nrbf.regularization = 0;
  best.leave_one_out = std::numeric_limits<double>::infinity();
  for (int k : kKnnNeighbours) {
    if (k > std::max<Eigen::Index>(1, centers.rows() - 1)) break;
    const double loo = centers.rows() < 2 ? 0.0 : knn_leave_one_out(centers, samples, k);
    if (loo < best.leave_one_out) {
      best.neighbours = k;
      best.leave_one_out = loo;
    }
  }
  return best;
}

MatrixXfR evaluate_interpolant(const Interpolant& f, const Eigen::Ref<const MatrixXfR>& q) {
  if (f.kind == InterpolantKind::nrbf) return evaluate_nrbf(f.nrbf, q);
  if (q.cols() != f.nrbf.centers.cols()) {
    throw std::invalid_argument(
        fmt::format("knn: queries must have {} columns (r_u), got {}", f.nrbf.centers.cols(), q.cols()));
  }
  MatrixXfR out(q.rows(), f.nrbf.weights.cols());
  for (Eigen::Index i = 0; i < q.rows(); ++i)
    out.row(i) = knn_at(f.nrbf.centers, f.nrbf.weights, f.neighbours, q.row(i)).cast<float>();
  return out;
}

}  // namespace phasecast::precompute
