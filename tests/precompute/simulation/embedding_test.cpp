// Render-mesh embeddings against what they must be: Loop subdivision weights
// reproduce affine functions and have the textbook stencils; barycentric
// weights in tets move every render point by the tets' affine motion, and a
// point far outside the tets is refused in one line.

#include "phasecast/precompute/simulation/embedding.h"
#include "error_of.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <random>

namespace phasecast::precompute {
namespace {

using phasecast::testing::error_of;

// A (n+1) x (n+1) grid with every quad split along the same diagonal:
// interior vertices have valence 6 (Loop's regular case).
struct Grid {
  Eigen::MatrixX3d X;
  Eigen::MatrixXi triangles;
  int n = 0;
  int at(int i, int j) const { return j * (n + 1) + i; }
};

Grid regular_grid(int n) {
  Grid g;
  g.n = n;
  g.X.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) g.X.row(g.at(i, j)) << i, j, 0;
  g.triangles.resize(2 * n * n, 3);
  int t = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      g.triangles.row(t++) << g.at(i, j), g.at(i + 1, j), g.at(i + 1, j + 1);
      g.triangles.row(t++) << g.at(i, j), g.at(i + 1, j + 1), g.at(i, j + 1);
    }
  return g;
}

Eigen::MatrixX3d times(const VertexEmbedding& W, const Eigen::MatrixX3d& X) {
  return Eigen::MatrixXd(W) * X;
}

TEST(LoopSubdivision, WeightsReproduceAffineFunctionsExactly) {
  Grid g = regular_grid(4);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (Eigen::Index v = 0; v < g.X.rows(); ++v)
    g.X.row(v) += Eigen::RowVector3d(u(rng), u(rng), u(rng)) * 0.3;
  Eigen::Matrix3d A;
  for (int k = 0; k < 9; ++k) A(k) = u(rng);
  const Eigen::RowVector3d b(0.3, -2, 5);
  for (int levels : {1, 2, 3}) {
    const Subdivision s = loop_subdivision(g.triangles, static_cast<int>(g.X.rows()), levels);
    ASSERT_EQ(s.triangles.rows(), g.triangles.rows() << (2 * levels));
    const Eigen::VectorXd sums = Eigen::MatrixXd(s.weights).rowwise().sum();
    EXPECT_LT((sums.array() - 1).abs().maxCoeff(), 1e-12) << levels << " levels";
    const Eigen::MatrixX3d moved = (g.X * A.transpose()).rowwise() + b;  // x -> A x + b
    const Eigen::MatrixX3d expected = (times(s.weights, g.X) * A.transpose()).rowwise() + b;
    EXPECT_LT((times(s.weights, moved) - expected).cwiseAbs().maxCoeff(), 1e-12) << levels << " levels";
  }
}

TEST(LoopSubdivision, OneLevelOfARegularGridHasTheTextbookStencils) {
  const Grid g = regular_grid(4);  // 25 vertices, 32 triangles, 56 edges
  const Subdivision s = loop_subdivision(g.triangles, 25, 1);
  ASSERT_EQ(s.weights.rows(), 25 + 56);
  const auto& W = s.weights;
  // Interior vertex, valence 6: 5/8 itself, 1/16 each neighbour (Loop's beta).
  const int v = g.at(2, 2);
  EXPECT_DOUBLE_EQ(W.coeff(v, v), 10.0 / 16);
  for (int nb : {g.at(1, 2), g.at(3, 2), g.at(2, 1), g.at(2, 3), g.at(1, 1), g.at(3, 3)})
    EXPECT_DOUBLE_EQ(W.coeff(v, nb), 1.0 / 16) << nb;
  EXPECT_EQ(W.row(v).nonZeros(), 7);
  // Boundary vertex: 3/4 itself, 1/8 each boundary neighbour.
  const int e = g.at(2, 0);
  EXPECT_DOUBLE_EQ(W.coeff(e, e), 3.0 / 4);
  EXPECT_DOUBLE_EQ(W.coeff(e, g.at(1, 0)), 1.0 / 8);
  EXPECT_DOUBLE_EQ(W.coeff(e, g.at(3, 0)), 1.0 / 8);
  EXPECT_EQ(W.row(e).nonZeros(), 3);
  // Edge points, found by where they lie: 3/8, 3/8, 1/8, 1/8 inside; 1/2, 1/2 on the boundary.
  const Eigen::MatrixX3d x = times(W, g.X);
  int interior = 0, boundary = 0;
  for (Eigen::Index p = 25; p < W.rows(); ++p) {
    std::vector<double> w;
    for (VertexEmbedding::InnerIterator it(W, p); it; ++it) w.push_back(it.value());
    std::sort(w.begin(), w.end());
    const bool on_rim = x(p, 0) == 0 || x(p, 0) == 4 || x(p, 1) == 0 || x(p, 1) == 4;
    if (on_rim) {
      ++boundary;
      EXPECT_EQ(w, (std::vector<double>{0.5, 0.5})) << "point " << p;
    } else {
      ++interior;
      EXPECT_EQ(w, (std::vector<double>{1.0 / 8, 1.0 / 8, 3.0 / 8, 3.0 / 8})) << "point " << p;
    }
  }
  EXPECT_EQ(boundary, 16);
  EXPECT_EQ(interior, 40);
  // The edge point between (1, 1) and (2, 1): its opposite vertices are (2, 2) and (1, 0).
  const Eigen::RowVector3d mid(1.5, 1, 0);
  for (Eigen::Index p = 25; p < W.rows(); ++p) {
    if (!x.row(p).isApprox(mid)) continue;
    EXPECT_DOUBLE_EQ(W.coeff(p, g.at(1, 1)), 3.0 / 8);
    EXPECT_DOUBLE_EQ(W.coeff(p, g.at(2, 1)), 3.0 / 8);
    EXPECT_DOUBLE_EQ(W.coeff(p, g.at(2, 2)), 1.0 / 8);
    EXPECT_DOUBLE_EQ(W.coeff(p, g.at(1, 0)), 1.0 / 8);
  }
}

TEST(LoopSubdivision, ClosedSurfaceUsesLoopsBetaAtEveryValence) {
  // Octahedron: every vertex has valence 4, beta = (5/8 - (3/8)^2) / 4 = 31/256.
  Eigen::MatrixXi T(8, 3);
  T << 0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5;
  const Subdivision s = loop_subdivision(T, 6, 1);
  EXPECT_EQ(s.weights.rows(), 6 + 12);
  EXPECT_DOUBLE_EQ(s.weights.coeff(4, 4), 1 - 4 * 31.0 / 256);
  EXPECT_DOUBLE_EQ(s.weights.coeff(4, 0), 31.0 / 256);
  EXPECT_EQ(s.weights.coeff(4, 5), 0.0);  // the opposite pole is no neighbour
}

// The unit cube in six tets around its diagonal 0-7 (corner index = x + 2y + 4z).
struct Cube {
  Eigen::VectorXd rest = Eigen::VectorXd(24);
  Eigen::MatrixX4i tets = Eigen::MatrixX4i(6, 4);
  Eigen::MatrixXi boundary = Eigen::MatrixXi(12, 3);
  Cube() {
    for (int c = 0; c < 8; ++c) rest.segment<3>(3 * c) << (c & 1), ((c >> 1) & 1), ((c >> 2) & 1);
    tets << 0, 1, 3, 7, 0, 1, 5, 7, 0, 2, 3, 7, 0, 2, 6, 7, 0, 4, 5, 7, 0, 4, 6, 7;
    boundary << 0, 1, 3, 0, 2, 3, 4, 5, 7, 4, 6, 7, 0, 1, 5, 0, 4, 5, 2, 3, 7, 2, 6, 7, 0, 2, 6, 0, 4, 6, 1,
        3, 7, 1, 5, 7;
  }
};

TEST(TetEmbedding, AnAffineMotionOfTheTetsMovesEveryRenderPointByTheSameMap) {
  const Cube cube;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1), out(0.01, 0.09);
  Eigen::MatrixX3d points(60, 3);
  for (int p = 0; p < 50; ++p) points.row(p) << u(rng), u(rng), u(rng);
  for (int p = 50; p < 60; ++p) {  // just outside a face, within the 0.1 m allowed
    points.row(p) << u(rng), u(rng), u(rng);
    points(p, p % 3) = p % 2 ? 1 + out(rng) : -out(rng);
  }
  const VertexEmbedding W = tet_embedding(points, cube.rest, cube.tets, cube.boundary, 0.1);
  ASSERT_EQ(W.rows(), 60);
  const Eigen::MatrixX3d X = Eigen::Map<const Eigen::Matrix<double, 8, 3, Eigen::RowMajor>>(cube.rest.data());
  EXPECT_LT((times(W, X) - points).cwiseAbs().maxCoeff(), 1e-14);  // the render rest is W X
  Eigen::Matrix3d A;
  A << 1.2, 0.3, -0.4, 0.1, 0.7, 0.2, -0.5, 0.6, 1.1;
  const Eigen::RowVector3d b(0.5, -1, 2);
  const Eigen::MatrixX3d moved = (X * A.transpose()).rowwise() + b;
  const Eigen::MatrixX3d expected = (points * A.transpose()).rowwise() + b;
  EXPECT_LT((times(W, moved) - expected).cwiseAbs().maxCoeff(), 1e-13);
  for (Eigen::Index p = 0; p < 50; ++p) {  // inside: convex weights of one tet
    EXPECT_EQ(W.row(p).nonZeros(), 4);
    for (VertexEmbedding::InnerIterator it(W, p); it; ++it) EXPECT_GE(it.value(), -1e-9) << "point " << p;
  }
}

TEST(TetEmbedding, APointFarOutsideTheTetsIsRefusedInOneLine) {
  const Cube cube;
  Eigen::MatrixX3d points(2, 3);
  points << 0.5, 0.5, 0.5, 0.5, 1.3, 0.5;
  const std::string message =
      error_of([&] { tet_embedding(points, cube.rest, cube.tets, cube.boundary, 0.1); });
  EXPECT_EQ(message,
            "render vertex 1 at (0.5, 1.3, 0.5) lies more than 0.1 m outside the tets (expected within 0.1 m "
            "of the surface)");
  points(1, 1) = 1.05;
  EXPECT_NO_THROW(tet_embedding(points, cube.rest, cube.tets, cube.boundary, 0.1));
  points(1, 1) = 1.15;
  EXPECT_EQ(error_of([&] { tet_embedding(points, cube.rest, cube.tets, cube.boundary, 0.1); }),
            "render vertex 1 at (0.5, 1.15, 0.5) lies more than 0.1 m outside the tets (expected within 0.1 "
            "m of the "
            "surface)");
}

}  // namespace
}  // namespace phasecast::precompute
