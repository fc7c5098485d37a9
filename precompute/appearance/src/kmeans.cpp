#include "phasecast/precompute/appearance/kmeans.h"

#include <fmt/format.h>

#include <limits>
#include <random>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

using MatrixXdR = RowMatrix<double>;

// Uniform double in [0, 1) from the top 53 bits: the same on every platform,
// unlike std::uniform_real_distribution.
double uniform(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

void check(const Eigen::Ref<const MatrixXfR>& X, const KMeansOptions& o) {
  if (X.rows() == 0 || X.cols() == 0) {
    throw std::invalid_argument(
        fmt::format("kmeans: data must be N x d with N, d >= 1, got {} x {}", X.rows(), X.cols()));
  }
  if (o.clusters < 1 || o.clusters > X.rows()) {
    throw std::invalid_argument(
        fmt::format("kmeans: clusters must be in 1..{} (the number of rows), got {}", X.rows(), o.clusters));
  }
  if (o.max_iterations < 0) {
    throw std::invalid_argument(fmt::format("kmeans: max_iterations must be >= 0, got {}", o.max_iterations));
  }
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    if (!X.row(i).allFinite()) throw std::invalid_argument(fmt::format("kmeans: row {} is not finite", i));
  }
}

// k-means++ (Arthur & Vassilvitskii 2007): each next seed is a row drawn with
// probability proportional to its squared distance to the nearest seed so far.
MatrixXdR seed_means(const MatrixXdR& X, int k, std::mt19937_64& rng) {
  const Eigen::Index N = X.rows();
  MatrixXdR means(k, X.cols());
  std::vector<bool> chosen(static_cast<size_t>(N), false);
  Eigen::Index first =
      std::min<Eigen::Index>(N - 1, static_cast<Eigen::Index>(uniform(rng) * static_cast<double>(N)));
  means.row(0) = X.row(first);
  chosen[static_cast<size_t>(first)] = true;
  Eigen::VectorXd d2 = (X.rowwise() - means.row(0)).rowwise().squaredNorm();
  for (int j = 1; j < k; ++j) {
    const double total = d2.sum();
    Eigen::Index pick = -1;
    if (total > 0) {
      double target = uniform(rng) * total;
      for (Eigen::Index i = 0; i < N && pick < 0; ++i) {
        target -= d2[i];
        if (target < 0 && d2[i] > 0) pick = i;
      }
      if (pick < 0) d2.maxCoeff(&pick);  // rounding left target >= 0: the farthest row
    } else {
      // Fewer distinct rows than k: take the first row not yet a seed.
      pick = 0;
      while (chosen[static_cast<size_t>(pick)]) ++pick;
    }
    chosen[static_cast<size_t>(pick)] = true;
    means.row(j) = X.row(pick);
    d2 = d2.cwiseMin((X.rowwise() - means.row(j)).rowwise().squaredNorm());
  }
  return means;
}

// Nearest mean of every row (ties to the lower cluster); returns whether any label changed.
bool assign(const MatrixXdR& X, const MatrixXdR& means, std::vector<std::int32_t>& labels,
            Eigen::VectorXd& d2) {
  bool changed = false;
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    Eigen::Index best = 0;
    const double dist = (means.rowwise() - X.row(i)).rowwise().squaredNorm().minCoeff(&best);
    d2[i] = dist;
    if (labels[static_cast<size_t>(i)] != best) {
      labels[static_cast<size_t>(i)] = static_cast<std::int32_t>(best);
      changed = true;
    }
  }
  return changed;
}

// Gives every empty cluster the row farthest from its mean (taken from a
// cluster with more than one member); returns the cluster sizes and sets
// `moved` when it had to.
std::vector<std::int32_t> fill_empty(const MatrixXdR& X, MatrixXdR& means, std::vector<std::int32_t>& labels,
                                     Eigen::VectorXd& d2, bool& moved) {
  moved = false;
  std::vector<std::int32_t> sizes(static_cast<size_t>(means.rows()), 0);
  for (const auto l : labels) ++sizes[static_cast<size_t>(l)];
  for (Eigen::Index j = 0; j < means.rows(); ++j) {
    if (sizes[static_cast<size_t>(j)] > 0) continue;
    Eigen::Index far = -1;
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      if (sizes[static_cast<size_t>(labels[static_cast<size_t>(i)])] > 1 && (far < 0 || d2[i] > d2[far]))
        far = i;
    }
    --sizes[static_cast<size_t>(labels[static_cast<size_t>(far)])];
    labels[static_cast<size_t>(far)] = static_cast<std::int32_t>(j);
    sizes[static_cast<size_t>(j)] = 1;
    means.row(j) = X.row(far);
    d2[far] = 0;
    moved = true;
  }
  return sizes;
}

void update_means(const MatrixXdR& X, const std::vector<std::int32_t>& labels,
                  const std::vector<std::int32_t>& sizes, MatrixXdR& means) {
  means.setZero();
  for (Eigen::Index i = 0; i < X.rows(); ++i) means.row(labels[static_cast<size_t>(i)]) += X.row(i);
  for (Eigen::Index j = 0; j < means.rows(); ++j) means.row(j) /= sizes[static_cast<size_t>(j)];
}

}  // namespace

KMeansResult kmeans(const Eigen::Ref<const MatrixXfR>& Xf, const KMeansOptions& o) {
  check(Xf, o);
  const MatrixXdR X = Xf.cast<double>();
  const Eigen::Index N = X.rows();
  std::mt19937_64 rng(o.seed);
  MatrixXdR means = seed_means(X, o.clusters, rng);
  KMeansResult r;
  r.labels.assign(static_cast<size_t>(N), -1);
  Eigen::VectorXd d2(N);
  bool moved = false;
  assign(X, means, r.labels, d2);
  r.sizes = fill_empty(X, means, r.labels, d2, moved);
  while (r.iterations < o.max_iterations) {
    update_means(X, r.labels, r.sizes, means);
    ++r.iterations;
    const bool changed = assign(X, means, r.labels, d2);
    r.sizes = fill_empty(X, means, r.labels, d2, moved);
    if (!changed && !moved) {
      r.converged = true;
      break;
    }
  }
  update_means(X, r.labels, r.sizes, means);
  r.representatives.assign(static_cast<size_t>(o.clusters), -1);
  std::vector<double> best(static_cast<size_t>(o.clusters), std::numeric_limits<double>::infinity());
  r.inertia = 0;
  for (Eigen::Index i = 0; i < N; ++i) {
    const auto j = static_cast<size_t>(r.labels[static_cast<size_t>(i)]);
    const double dist = (X.row(i) - means.row(static_cast<Eigen::Index>(j))).squaredNorm();
    r.inertia += dist;
    if (dist < best[j]) {
      best[j] = dist;
      r.representatives[j] = static_cast<std::int32_t>(i);
    }
  }
  r.means = means.cast<float>();
  return r;
}

}  // namespace phasecast::precompute
