// The whole appearance model (§4) on the synthetic plate package: k-means on
// q_u, shadowed transfer of each representative's deformed mesh, transfer
// SVD and NRBF, written into a package that validates and reads back.

#include "phasecast/core/mesh_geometry.h"
#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/appearance/transfer_appearance.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>

namespace phasecast {
namespace {

using namespace precompute;

MatrixXfR transfer_fields(const core::ScenePackage& p, const KMeansResult& clusters) {
  const int S = p.mesh.points();
  MatrixXfR fields(static_cast<Eigen::Index>(clusters.representatives.size()), 48 * S);
  TransferOptions o;
  o.mode = TransferMode::shadowed;
  o.rays = 128;
  for (size_t j = 0; j < clusters.representatives.size(); ++j) {
    const Eigen::VectorXf x = p.reduction.mean_shape +
                              p.reduction.U_u * p.portrait.q_u.row(clusters.representatives[j]).transpose();
    const MatrixXfR positions = Eigen::Map<const MatrixXfR>(x.data(), S, 3);
    const MatrixXfR T =
        compute_transfer(positions, p.mesh.triangles, core::vertex_normals(positions, p.mesh.triangles), o);
    fields.row(static_cast<Eigen::Index>(j)) = Eigen::Map<const Eigen::RowVectorXf>(T.data(), 48 * S);
  }
  return fields;
}

TEST(Appearance, FillsAValidPackage) {
  core::ScenePackage p = testing::make_plate_package({.grid = 6, .appearance = false});
  const auto clusters = kmeans(p.portrait.q_u, {.clusters = 8, .seed = 3});
  const MatrixXfR fields = transfer_fields(p, clusters);
  const auto model = fit_appearance_model(p.portrait.q_u, clusters, fields, {.reduction = {.eps_a = 1e-3}});
  const auto& a = model.appearance;
  ASSERT_GE(a.rank(), 1);
  EXPECT_EQ(a.clusters(), 8);
  EXPECT_EQ(a.cluster_nodes, clusters.representatives);
  EXPECT_EQ(model.q_a.rows(), p.portrait.nodes());
  EXPECT_EQ(model.q_a.cols(), a.rank());
  EXPECT_EQ(model.leave_one_out.errors.size(), 8);
  // At a cluster node the interpolant returns (nearly) that node's own q_a^j.
  const auto r = reduce_transfer(fields, {.eps_a = 1e-3});
  for (int j = 0; j < 8; ++j) {
    const Eigen::VectorXf got = model.q_a.row(a.cluster_nodes[static_cast<size_t>(j)]).transpose();
    EXPECT_LT((got - r.Q_a.col(j)).norm(), 0.05f * r.Q_a.norm()) << "cluster " << j;
  }
  p.appearance = a;
  p.portrait.q_a = model.q_a;
  p.attributes.eps_a = 1e-3;
  const auto path = testing::scratch_dir("appearance_package") / "plate.h5";
  core::write_package(p, path);  // validates
  const auto back = core::read_package(path);
  ASSERT_TRUE(back.appearance.has_value());
  EXPECT_EQ(back.appearance->U_a, a.U_a);
  EXPECT_EQ(back.appearance->nrbf_weights, a.nrbf_weights);
  EXPECT_EQ(back.portrait.q_a, model.q_a);
}

TEST(Appearance, OneClusterHasRankZero) {
  core::ScenePackage p = testing::make_plate_package({.grid = 4, .appearance = false});
  const auto clusters = kmeans(p.portrait.q_u, {.clusters = 1});
  const auto model = fit_appearance_model(p.portrait.q_u, clusters, transfer_fields(p, clusters), {});
  EXPECT_EQ(model.appearance.rank(), 0);
  EXPECT_EQ(model.q_a.rows(), p.portrait.nodes());
  EXPECT_EQ(model.q_a.cols(), 0);
  EXPECT_EQ(model.leave_one_out.errors.size(), 0);
  p.appearance = model.appearance;
  p.portrait.q_a = model.q_a;
  EXPECT_NO_THROW(core::validate_package(p, "one cluster"));
}

TEST(Appearance, RejectsMismatchedFields) {
  core::ScenePackage p = testing::make_plate_package({.grid = 4, .appearance = false});
  const auto clusters = kmeans(p.portrait.q_u, {.clusters = 3});
  try {
    fit_appearance_model(p.portrait.q_u, clusters, MatrixXfR::Zero(2, 48 * p.mesh.points()), {});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "fit_appearance_model: expected one transfer field per cluster (3), got 2");
  }
}

}  // namespace
}  // namespace phasecast
