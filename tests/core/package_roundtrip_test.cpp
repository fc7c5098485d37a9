// Writing and reading a package reproduces it exactly; writes are atomic.

#include "phasecast/core/basis.h"
#include "phasecast/core/hash.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>

namespace phasecast {
namespace {

using core::ScenePackage;

void expect_same(const ScenePackage& a, const ScenePackage& b) {
  EXPECT_EQ(a.attributes.scene, b.attributes.scene);
  EXPECT_EQ(a.attributes.dt, b.attributes.dt);
  EXPECT_EQ(a.attributes.beta, b.attributes.beta);
  EXPECT_EQ(a.attributes.blend_lambda, b.attributes.blend_lambda);
  EXPECT_EQ(a.attributes.camera, b.attributes.camera);
  EXPECT_EQ(a.mesh.rest_positions, b.mesh.rest_positions);
  EXPECT_EQ(a.mesh.triangles, b.mesh.triangles);
  EXPECT_EQ(a.mesh.normals, b.mesh.normals);
  EXPECT_EQ(a.mesh.deformable, b.mesh.deformable);
  EXPECT_EQ(a.mesh.attached, b.mesh.attached);
  EXPECT_EQ(a.palette.names, b.palette.names);
  EXPECT_EQ(a.palette.alpha_impulse, b.palette.alpha_impulse);
  EXPECT_EQ(a.palette.alpha_forcing, b.palette.alpha_forcing);
  EXPECT_EQ(a.palette.transitions, b.palette.transitions);
  EXPECT_EQ(a.palette.on_end, b.palette.on_end);
  EXPECT_EQ(a.palette.group, b.palette.group);
  EXPECT_EQ(a.palette.max_in_a_row, b.palette.max_in_a_row);
  ASSERT_EQ(a.palette.kinematics.size(), b.palette.kinematics.size());
  for (size_t i = 0; i < a.palette.kinematics.size(); ++i) {
    const auto &ka = a.palette.kinematics[i], &kb = b.palette.kinematics[i];
    EXPECT_EQ(ka.axis, kb.axis);
    EXPECT_EQ(ka.pivot, kb.pivot);
    EXPECT_EQ(ka.rotational, kb.rotational);
    EXPECT_EQ(ka.rate, kb.rate);
    EXPECT_EQ(ka.range_max, kb.range_max);
  }
  EXPECT_EQ(a.reduction.mean_shape, b.reduction.mean_shape);
  EXPECT_EQ(a.reduction.U_u, b.reduction.U_u);
  EXPECT_EQ(a.reduction.singular_values, b.reduction.singular_values);
  EXPECT_EQ(a.reduction.rel_error, b.reduction.rel_error);
  EXPECT_EQ(a.portrait.q_u, b.portrait.q_u);
  EXPECT_EQ(a.portrait.qdot_u, b.portrait.qdot_u);
  EXPECT_EQ(a.portrait.q_a, b.portrait.q_a);
  EXPECT_EQ(a.portrait.irf_start, b.portrait.irf_start);
  EXPECT_EQ(a.portrait.irf_length, b.portrait.irf_length);
  EXPECT_EQ(a.portrait.irf_palette, b.portrait.irf_palette);
  EXPECT_EQ(a.portrait.nearest_irf, b.portrait.nearest_irf);
  EXPECT_EQ(a.portrait.support, b.portrait.support);
  ASSERT_EQ(a.appearance.has_value(), b.appearance.has_value());
  if (a.appearance) {
    EXPECT_EQ(a.appearance->mean_transfer, b.appearance->mean_transfer);
    EXPECT_EQ(a.appearance->U_a, b.appearance->U_a);
    EXPECT_EQ(a.appearance->cluster_nodes, b.appearance->cluster_nodes);
    EXPECT_EQ(a.appearance->nrbf_weights, b.appearance->nrbf_weights);
    EXPECT_EQ(a.appearance->nrbf_regularization, b.appearance->nrbf_regularization);
  }
}

TEST(PackageRoundTrip, WithAppearanceIsExact) {
  const auto dir = testing::scratch_dir("roundtrip_appearance");
  const ScenePackage written = testing::make_plate_package();
  core::write_package(written, dir / "plate.h5");
  expect_same(written, core::read_package(dir / "plate.h5"));
}

TEST(PackageRoundTrip, WithoutAppearanceIsExact) {
  const auto dir = testing::scratch_dir("roundtrip_plain");
  testing::PlateOptions o;
  o.appearance = false;
  const ScenePackage written = testing::make_plate_package(o);
  core::write_package(written, dir / "plate.h5");
  const ScenePackage read = core::read_package(dir / "plate.h5");
  expect_same(written, read);
  EXPECT_EQ(read.rank_a(), 0);
  EXPECT_EQ(read.portrait.q_a.cols(), 0);
}

TEST(PackageRoundTrip, WriteIsAtomicAndLeavesNoTemporaryFile) {
  const auto dir = testing::scratch_dir("roundtrip_atomic");
  core::write_package(testing::make_plate_package(), dir / "plate.h5");
  // Overwriting an existing package with an invalid one is refused before any
  // byte is written: the old package stays readable.
  ScenePackage bad = testing::make_plate_package();
  bad.portrait.irf_palette[0] = 7;
  EXPECT_THROW(core::write_package(bad, dir / "plate.h5"), core::PackageError);
  EXPECT_NO_THROW(core::read_package(dir / "plate.h5"));
  int files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1);
}

TEST(PackageRoundTrip, SamePackageGivesTheSameBytes) {
  // Recordings and clients name packages by content hash: writing must be deterministic.
  const auto dir = testing::scratch_dir("roundtrip_bytes");
  core::write_package(testing::make_plate_package(), dir / "a.h5");
  core::write_package(testing::make_plate_package(), dir / "b.h5");
  EXPECT_EQ(core::file_content_hash(dir / "a.h5"), core::file_content_hash(dir / "b.h5"));
}

TEST(PackageRoundTrip, FixtureIsAConsistentPhasePortrait) {
  const ScenePackage p = testing::make_plate_package();
  // U_u orthonormal (eq. 4) and Q_u = S V^T: columns of q_u orthogonal with norms sigma (eq. 6).
  const Eigen::MatrixXf UtU = p.reduction.U_u.transpose() * p.reduction.U_u;
  EXPECT_TRUE(UtU.isIdentity(1e-4f));
  const Eigen::MatrixXf QtQ = p.portrait.q_u.transpose() * p.portrait.q_u;
  for (int i = 0; i < p.rank_u(); ++i) {
    EXPECT_NEAR(std::sqrt(QtQ(i, i)), p.reduction.singular_values[i], 1e-3f * p.reduction.singular_values[0]);
  }
  // The nearest-IRF cache of an IRF's own start node is that IRF (distance 0).
  for (int i = 0; i < p.portrait.irf_count(); ++i) {
    const int start = p.portrait.irf_start[static_cast<size_t>(i)];
    const int d = p.portrait.irf_palette[static_cast<size_t>(i)];
    EXPECT_EQ(p.portrait.irf_start[static_cast<size_t>(p.portrait.nearest_irf(start, d))], start);
  }
  EXPECT_GT(p.rank_a(), 0);
}

TEST(BasisParts, CoverEverythingAThinClientNeeds) {
  const ScenePackage p = testing::make_plate_package();
  const auto parts = core::basis_parts(p);
  ASSERT_EQ(parts.size(), 8u);
  EXPECT_EQ(parts[5].name, "U_u");
  EXPECT_EQ(parts[5].bytes.size(), sizeof(float) * 3 * p.mesh.points() * p.rank_u());
  EXPECT_EQ(parts[7].shape,
            (std::vector<std::uint64_t>{48u * p.mesh.points(), static_cast<std::uint64_t>(p.rank_a())}));
  EXPECT_EQ(core::reduced_state_bytes(p), sizeof(float) * (p.rank_u() + p.rank_a() + 12));
}

}  // namespace
}  // namespace phasecast
