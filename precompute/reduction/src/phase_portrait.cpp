#include "phasecast/precompute/reduction/phase_portrait.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace phasecast::precompute {

double default_beta(const MatrixXfR& q_u, const MatrixXfR& qdot_u) {
  if (q_u.rows() == 0) return 1.0;
  const double max_q = q_u.rowwise().squaredNorm().maxCoeff();
  const double max_v = qdot_u.rowwise().squaredNorm().maxCoeff();
  return max_v > 0 ? max_q / max_v : 1.0;
}

namespace {

// Rows [q, sqrt(beta) q̇] in double: the prefilter's points.
Eigen::MatrixXd phase_points_double(const MatrixXfR& q, const MatrixXfR& qdot, double beta) {
  Eigen::MatrixXd x(q.rows(), 2 * q.cols());
  x.leftCols(q.cols()) = q.cast<double>();
  x.rightCols(q.cols()) = qdot.cast<double>() * std::sqrt(beta);
  return x;
}

// Eq. 9 between nodes a and b, each difference taken in double: the
// distance the cache is exact under.
double eq9_squared(const MatrixXfR& q, const MatrixXfR& qdot, double beta, Eigen::Index a, Eigen::Index b) {
  return (q.row(a).cast<double>() - q.row(b).cast<double>()).squaredNorm() +
         beta * (qdot.row(a).cast<double>() - qdot.row(b).cast<double>()).squaredNorm();
}

// The IRFs of palette entry d, in index order.
std::vector<std::int32_t> irfs_of(const std::vector<std::int32_t>& irf_palette, int d) {
  std::vector<std::int32_t> irfs;
  for (size_t i = 0; i < irf_palette.size(); ++i)
    if (irf_palette[i] == d) irfs.push_back(static_cast<std::int32_t>(i));
  return irfs;
}

}  // namespace

MatrixXiR nearest_irf_cache(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta,
                            const std::vector<std::int32_t>& irf_start,
                            const std::vector<std::int32_t>& irf_length,
                            const std::vector<std::int32_t>& irf_palette, int palette_size) {
  const Eigen::Index N = q_u.rows();
  const Eigen::MatrixXd x = phase_points_double(q_u, qdot_u, beta);
  const Eigen::VectorXd x_norm = x.rowwise().squaredNorm();
  MatrixXiR cache = MatrixXiR::Constant(N, palette_size, -1);
  constexpr Eigen::Index kBlock = 1024;
  // What the rounding of |a|^2 + |b|^2 - 2 a.b in double can hide, relative
  // to |a|^2 + |b|^2: every start within it of the least score is measured
  // again directly, so the product only prefilters.
  constexpr double kRounding = 1e-9;
  const double band = kSameStartFraction * std::sqrt(x_norm.size() ? x_norm.maxCoeff() : 0.0);

  for (int d = 0; d < palette_size; ++d) {
    const std::vector<std::int32_t> irfs = irfs_of(irf_palette, d);
    if (irfs.empty()) continue;
    Eigen::MatrixXd starts(static_cast<Eigen::Index>(irfs.size()), x.cols());
    for (size_t k = 0; k < irfs.size(); ++k)
      starts.row(static_cast<Eigen::Index>(k)) = x.row(irf_start[static_cast<size_t>(irfs[k])]);
    const Eigen::VectorXd s_norm = starts.rowwise().squaredNorm();
    const double s_norm_max = s_norm.maxCoeff();
    for (Eigen::Index first = 0; first < N; first += kBlock) {
      const Eigen::Index count = std::min(kBlock, N - first);
      Eigen::MatrixXd score = -2.0 * (x.middleRows(first, count) * starts.transpose());
      score.rowwise() += s_norm.transpose();
      for (Eigen::Index j = 0; j < count; ++j) {
        const Eigen::Index node = first + j;
        const double least = score.row(j).minCoeff();
        const double slack = kRounding * (x_norm[node] + s_norm_max);
        double nearest = std::numeric_limits<double>::infinity();
        for (Eigen::Index k = 0; k < score.cols(); ++k) {
          if (score(j, k) > least + slack) continue;
          const auto irf = static_cast<size_t>(irfs[static_cast<size_t>(k)]);
          nearest = std::min(nearest, eq9_squared(q_u, qdot_u, beta, node, irf_start[irf]));
        }
        // Of the starts within the band, the longest IRF, then the nearest, then
        // the first sampled (irfs is in index order).
        const double reach = std::sqrt(nearest) + band;
        double best = std::numeric_limits<double>::infinity();
        std::int32_t best_length = 0;
        for (Eigen::Index k = 0; k < score.cols(); ++k) {
          if (score(j, k) > reach * reach - x_norm[node] + slack) continue;
          const auto irf = static_cast<size_t>(irfs[static_cast<size_t>(k)]);
          const double distance = eq9_squared(q_u, qdot_u, beta, node, irf_start[irf]);
          if (std::sqrt(distance) > reach) continue;
          if (irf_length[irf] > best_length || (irf_length[irf] == best_length && distance < best)) {
            best = distance;
            best_length = irf_length[irf];
            cache(node, d) = static_cast<std::int32_t>(irf);
          }
        }
      }
    }
  }
  return cache;
}

}  // namespace phasecast::precompute
