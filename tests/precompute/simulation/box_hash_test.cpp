// The contact broad phase against brute force: every box that intersects a
// query, each once, ascending, for boxes of very different sizes on both
// sides of the origin (large boxes span many cells; each is listed once).

#include "box_hash.h"

#include <gtest/gtest.h>

#include <random>

namespace phasecast::precompute {
namespace {

Eigen::AlignedBox3d random_box(std::mt19937& rng, double largest) {
  std::uniform_real_distribution<double> centre(-1.0, 1.0), size(0.0, 1.0);
  const Eigen::Vector3d c(centre(rng), centre(rng), centre(rng));
  // Sizes from a millimetre to `largest`, skewed small as in a mesh with a few fast parts.
  const Eigen::Vector3d half =
      0.5 * largest * Eigen::Vector3d(size(rng), size(rng), size(rng)).array().pow(4).matrix();
  return {c - half - Eigen::Vector3d::Constant(1e-3), c + half + Eigen::Vector3d::Constant(1e-3)};
}

TEST(BoxHash, ListsEveryIntersectingBoxOnceInOrder) {
  std::mt19937 rng(11);
  std::vector<Eigen::AlignedBox3d> boxes;
  for (int i = 0; i < 2000; ++i) boxes.push_back(random_box(rng, 0.8));
  const BoxHash hash(boxes);
  std::vector<int> found;
  size_t pairs = 0;
  for (int q = 0; q < 500; ++q) {
    const auto query = random_box(rng, q % 10 == 0 ? 1.5 : 0.2);
    std::vector<int> brute;
    for (int i = 0; i < static_cast<int>(boxes.size()); ++i)
      if (boxes[static_cast<size_t>(i)].intersects(query)) brute.push_back(i);
    hash.overlapping(query, found);
    ASSERT_EQ(found, brute) << "query " << q;
    pairs += brute.size();
  }
  EXPECT_GT(pairs, 1000u);  // not vacuous: the queries meet many boxes, large ones among them
}

}  // namespace
}  // namespace phasecast::precompute
