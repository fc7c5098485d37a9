// k-means++ on data with a known clustering.

#include "phasecast/precompute/appearance/kmeans.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

namespace phasecast {
namespace {

using precompute::kmeans;
using precompute::KMeansOptions;

// Three blobs of 40 points in 4-D, well separated, uniform noise of +-0.5.
MatrixXfR blobs(std::vector<int>* truth) {
  std::mt19937_64 rng(42);
  const float centre[3][4] = {{0, 0, 0, 0}, {10, 0, 0, 0}, {0, 10, 0, 5}};
  MatrixXfR X(120, 4);
  for (int i = 0; i < 120; ++i) {
    const int b = i % 3;
    truth->push_back(b);
    for (int d = 0; d < 4; ++d) {
      X(i, d) = centre[b][d] + static_cast<float>(static_cast<double>(rng() >> 11) * 0x1.0p-53 - 0.5);
    }
  }
  return X;
}

TEST(KMeans, RecoversSeparatedBlobs) {
  std::vector<int> truth;
  const MatrixXfR X = blobs(&truth);
  const auto r = kmeans(X, {.clusters = 3, .seed = 5});
  ASSERT_EQ(r.labels.size(), 120u);
  EXPECT_TRUE(r.converged);
  // One cluster per blob, a bijection.
  std::vector<int> blob_of_cluster(3, -1);
  for (size_t i = 0; i < truth.size(); ++i) {
    auto& b = blob_of_cluster[static_cast<size_t>(r.labels[i])];
    if (b < 0) b = truth[i];
    EXPECT_EQ(b, truth[i]) << "row " << i;
  }
  EXPECT_EQ(std::set<int>(blob_of_cluster.begin(), blob_of_cluster.end()).size(), 3u);
  EXPECT_THAT(r.sizes, ::testing::ElementsAre(40, 40, 40));
  double inertia = 0;
  for (int j = 0; j < 3; ++j) {
    // Each mean is its members' mean; the representative is the member nearest it.
    Eigen::RowVectorXd mean = Eigen::RowVectorXd::Zero(4);
    for (int i = 0; i < 120; ++i) {
      if (r.labels[static_cast<size_t>(i)] == j) mean += X.row(i).cast<double>() / 40;
    }
    EXPECT_LT((mean - r.means.row(j).cast<double>()).norm(), 1e-5);
    int nearest = -1;
    for (int i = 0; i < 120; ++i) {
      if (r.labels[static_cast<size_t>(i)] != j) continue;
      const double d = (X.row(i).cast<double>() - mean).squaredNorm();
      inertia += d;
      if (nearest < 0 || d < (X.row(nearest).cast<double>() - mean).squaredNorm()) nearest = i;
    }
    EXPECT_EQ(r.representatives[static_cast<size_t>(j)], nearest);
  }
  EXPECT_NEAR(r.inertia, inertia, 1e-6 * inertia);
}

TEST(KMeans, DeterministicForASeedAndStableAcrossSeeds) {
  std::vector<int> truth;
  const MatrixXfR X = blobs(&truth);
  const auto a = kmeans(X, {.clusters = 3, .seed = 11});
  const auto b = kmeans(X, {.clusters = 3, .seed = 11});
  EXPECT_EQ(a.labels, b.labels);
  EXPECT_EQ(a.means, b.means);
  EXPECT_EQ(a.representatives, b.representatives);
  const auto c = kmeans(X, {.clusters = 3, .seed = 12345});
  EXPECT_NEAR(c.inertia, a.inertia, 1e-9 * a.inertia);  // same partition, maybe renumbered
}

TEST(KMeans, OneDimensionalKnownAnswer) {
  MatrixXfR X(6, 1);
  X << 0, 1, 2, 10, 11, 12;
  const auto r = kmeans(X, {.clusters = 2, .seed = 3});
  const int low = r.means(0, 0) < r.means(1, 0) ? 0 : 1;
  EXPECT_FLOAT_EQ(r.means(low, 0), 1.0f);
  EXPECT_FLOAT_EQ(r.means(1 - low, 0), 11.0f);
  EXPECT_EQ(r.representatives[static_cast<size_t>(low)], 1);
  EXPECT_EQ(r.representatives[static_cast<size_t>(1 - low)], 4);
  EXPECT_DOUBLE_EQ(r.inertia, 4.0);
}

TEST(KMeans, EveryClusterKeepsAMemberWhenRowsRepeat) {
  MatrixXfR X = MatrixXfR::Ones(5, 2);
  const auto r = kmeans(X, {.clusters = 3, .seed = 1});
  EXPECT_EQ(std::set<int>(r.representatives.begin(), r.representatives.end()).size(), 3u);
  EXPECT_EQ(r.sizes[0] + r.sizes[1] + r.sizes[2], 5);
  for (const auto s : r.sizes) EXPECT_GE(s, 1);
  EXPECT_EQ(r.inertia, 0.0);
}

TEST(KMeans, ExtremeClusterCounts) {
  std::vector<int> truth;
  const MatrixXfR X = blobs(&truth);
  const auto one = kmeans(X, {.clusters = 1});
  EXPECT_LT((one.means.row(0) - X.colwise().mean()).norm(), 1e-5f);
  const auto all = kmeans(X.topRows(7), {.clusters = 7});
  EXPECT_EQ(all.inertia, 0.0);
  EXPECT_EQ(std::set<int>(all.representatives.begin(), all.representatives.end()).size(), 7u);
}

std::string failure_of(const MatrixXfR& X, KMeansOptions o) {
  try {
    kmeans(X, o);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}

TEST(KMeansRejects, BadInput) {
  MatrixXfR X = MatrixXfR::Random(6, 2);
  EXPECT_EQ(failure_of(X, {.clusters = 0}), "kmeans: clusters must be in 1..6 (the number of rows), got 0");
  EXPECT_EQ(failure_of(X, {.clusters = 7}), "kmeans: clusters must be in 1..6 (the number of rows), got 7");
  EXPECT_EQ(failure_of(X, {.clusters = 2, .seed = 1, .max_iterations = -1}),
            "kmeans: max_iterations must be >= 0, got -1");
  X(4, 1) = NAN;
  EXPECT_EQ(failure_of(X, {.clusters = 2}), "kmeans: row 4 is not finite");
  EXPECT_EQ(failure_of(MatrixXfR(0, 3), {.clusters = 1}),
            "kmeans: data must be N x d with N, d >= 1, got 0 x 3");
}

}  // namespace
}  // namespace phasecast
