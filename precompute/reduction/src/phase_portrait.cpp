#include "phasecast/precompute/reduction/phase_portrait.h"

#include "phasecast/core/phase_space.h"

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

MatrixXiR nearest_irf_cache(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta,
                            const std::vector<std::int32_t>& irf_start,
                            const std::vector<std::int32_t>& irf_palette, int palette_size) {
  const Eigen::Index N = q_u.rows();
  const Eigen::MatrixXf x = core::phase_points(q_u, qdot_u, beta);
  MatrixXiR cache = MatrixXiR::Constant(N, palette_size, -1);
  constexpr Eigen::Index kBlock = 1024;

  for (int d = 0; d < palette_size; ++d) {
    std::vector<std::int32_t> irfs;
    for (size_t i = 0; i < irf_palette.size(); ++i) {
      if (irf_palette[i] == d) irfs.push_back(static_cast<std::int32_t>(i));
    }
    if (irfs.empty()) continue;
    Eigen::MatrixXf starts(static_cast<Eigen::Index>(irfs.size()), x.cols());
    for (size_t k = 0; k < irfs.size(); ++k)
      starts.row(static_cast<Eigen::Index>(k)) = x.row(irf_start[static_cast<size_t>(irfs[k])]);
    const Eigen::VectorXf s_norm = starts.rowwise().squaredNorm();

    // |a - b|^2 = |a|^2 + |b|^2 - 2 a.b; |a|^2 is constant per row, so the
    // argmin needs only |b|^2 - 2 a.b.
    for (Eigen::Index first = 0; first < N; first += kBlock) {
      const Eigen::Index count = std::min(kBlock, N - first);
      Eigen::MatrixXf score = -2.0f * (x.middleRows(first, count) * starts.transpose());
      score.rowwise() += s_norm.transpose();
      for (Eigen::Index j = 0; j < count; ++j) {
        Eigen::Index best = 0;
        score.row(j).minCoeff(&best);
        cache(first + j, d) = irfs[static_cast<size_t>(best)];
      }
    }
  }
  return cache;
}

}  // namespace phasecast::precompute
