#pragma once
// K-means clustering of state nodes in q_u (§4.3; Nelles 2000), with
// k-means++ seeding. Deterministic: the same data and seed give the same
// clusters on every machine (the generator is std::mt19937_64, whose output
// the standard fixes, turned into doubles without library distributions).

#include "phasecast/core/eigen_types.h"

#include <cstdint>
#include <vector>

namespace phasecast::precompute {

struct KMeansOptions {
  int clusters = 1;          // k = N_a
  std::uint64_t seed = 1;    // k-means++ seeding
  int max_iterations = 100;  // Lloyd iterations after seeding
};

struct KMeansResult {
  MatrixXfR means;                            // k x d cluster means
  std::vector<std::int32_t> labels;           // N: cluster of each row
  std::vector<std::int32_t> representatives;  // k: member row nearest each mean (distinct rows)
  std::vector<std::int32_t> sizes;            // k: members per cluster (all >= 1)
  int iterations = 0;                         // Lloyd iterations run
  bool converged = false;                     // labels stopped changing before max_iterations
  double inertia = 0;                         // sum of squared distances to the assigned means
};

// Clusters the rows of X.
//   @param[in] X        #N by d data (e.g. q_u, one state node per row)
//   @param[in] options  k (1 <= k <= N), seed, iteration cap
//   @return             means, labels, representatives (the node nearest each
//                       cluster mean among its members, ties to the lower row)
// Every cluster is non-empty: a cluster left empty takes the row farthest
// from its mean. Throws std::invalid_argument for k out of range, an empty
// X, or non-finite entries.
KMeansResult kmeans(const Eigen::Ref<const MatrixXfR>& X, const KMeansOptions& options);

}  // namespace phasecast::precompute
