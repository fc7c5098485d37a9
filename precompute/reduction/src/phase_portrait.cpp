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

// Velocities read from one scene's palette: equal unless they differ beyond
// float rounding.
bool same_velocity(const SupportVelocity& a, const SupportVelocity& b) {
  for (size_t i = 0; i < a.size(); ++i)
    if (std::abs(a[i] - b[i]) > 1e-9 + 1e-6 * std::max(std::abs(a[i]), std::abs(b[i]))) return false;
  return true;
}

// Which IRFs of `irfs` may play from a node whose support moves at `v`: those
// whose start moved at it, or all of them when none did.
std::vector<char> candidates_at(const std::vector<std::int32_t>& irfs,
                                const std::vector<std::int32_t>& irf_start,
                                const std::vector<SupportVelocity>& support_velocity,
                                const SupportVelocity& v) {
  std::vector<char> ok(irfs.size(), 1);
  if (support_velocity.empty()) return ok;
  bool any = false;
  for (size_t k = 0; k < irfs.size(); ++k) {
    ok[k] = same_velocity(support_velocity[static_cast<size_t>(irf_start[static_cast<size_t>(irfs[k])])], v);
    any = any || ok[k];
  }
  if (!any) std::fill(ok.begin(), ok.end(), 1);
  return ok;
}

}  // namespace

std::vector<SupportVelocity> support_velocities(const std::vector<std::int32_t>& irf_start,
                                                const std::vector<std::int32_t>& irf_length,
                                                const std::vector<std::int32_t>& irf_palette,
                                                const std::vector<std::uint8_t>& continues,
                                                const std::vector<SupportVelocity>& held) {
  const size_t n = irf_start.size();
  if (irf_length.size() != n || irf_palette.size() != n || continues.size() != n)
    throw std::invalid_argument(
        "support_velocities: expected one length, palette entry and continues flag per IRF");
  std::vector<SupportVelocity> v(n ? static_cast<size_t>(irf_start.back() + irf_length.back()) : 0,
                                 SupportVelocity{});
  size_t next = 0;
  for (size_t i = 0; i < n; ++i) {
    const auto entry = static_cast<size_t>(irf_palette[i]);
    if (entry >= held.size())
      throw std::invalid_argument("support_velocities: expected a held velocity per entry");
    const auto first = static_cast<size_t>(irf_start[i]), end = first + static_cast<size_t>(irf_length[i]);
    if (first != next || end > v.size())
      throw std::invalid_argument("support_velocities: expected consecutive IRFs");
    next = end;
    std::fill(v.begin() + static_cast<std::ptrdiff_t>(first), v.begin() + static_cast<std::ptrdiff_t>(end),
              held[entry]);
    v[first] = (i > 0 && continues[i]) ? held[static_cast<size_t>(irf_palette[i - 1])] : SupportVelocity{};
  }
  return v;
}

MatrixXiR nearest_irf_cache(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta,
                            const std::vector<std::int32_t>& irf_start,
                            const std::vector<std::int32_t>& irf_length,
                            const std::vector<std::int32_t>& irf_palette, int palette_size,
                            const std::vector<SupportVelocity>& support_velocity) {
  const Eigen::Index N = q_u.rows();
  if (!support_velocity.empty() && static_cast<Eigen::Index>(support_velocity.size()) != N)
    throw std::invalid_argument("nearest_irf_cache: expected one support velocity per node");
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
    std::vector<std::pair<SupportVelocity, std::vector<char>>> by_velocity;  // a palette has few
    for (Eigen::Index first = 0; first < N; first += kBlock) {
      const Eigen::Index count = std::min(kBlock, N - first);
      Eigen::MatrixXd score = -2.0 * (x.middleRows(first, count) * starts.transpose());
      score.rowwise() += s_norm.transpose();
      for (Eigen::Index j = 0; j < count; ++j) {
        const Eigen::Index node = first + j;
        const SupportVelocity v =
            support_velocity.empty() ? SupportVelocity{} : support_velocity[static_cast<size_t>(node)];
        auto known = std::find_if(by_velocity.begin(), by_velocity.end(),
                                  [&](const auto& known_v) { return same_velocity(known_v.first, v); });
        if (known == by_velocity.end())
          known =
              by_velocity.insert(by_velocity.end(), {v, candidates_at(irfs, irf_start, support_velocity, v)});
        const std::vector<char>& ok = known->second;
        double least = std::numeric_limits<double>::infinity();
        for (Eigen::Index k = 0; k < score.cols(); ++k)
          if (ok[static_cast<size_t>(k)]) least = std::min(least, score(j, k));
        const double slack = kRounding * (x_norm[node] + s_norm_max);
        double nearest = std::numeric_limits<double>::infinity();
        for (Eigen::Index k = 0; k < score.cols(); ++k) {
          if (!ok[static_cast<size_t>(k)] || score(j, k) > least + slack) continue;
          const auto irf = static_cast<size_t>(irfs[static_cast<size_t>(k)]);
          nearest = std::min(nearest, eq9_squared(q_u, qdot_u, beta, node, irf_start[irf]));
        }
        // Of the starts within the band, the longest IRF, then the nearest, then
        // the first sampled (irfs is in index order).
        const double reach = std::sqrt(nearest) + band;
        double best = std::numeric_limits<double>::infinity();
        std::int32_t best_length = 0;
        for (Eigen::Index k = 0; k < score.cols(); ++k) {
          if (!ok[static_cast<size_t>(k)] || score(j, k) > reach * reach - x_norm[node] + slack) continue;
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
