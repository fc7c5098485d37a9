// Streamed model reduction from an orbit store file, orbit filtering, and the
// package assembled from them.

#include "error_of.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/precompute/reduction/displacement_reduction.h"
#include "phasecast/precompute/sampling/irf_sampler.h"
#include "phasecast/precompute/sampling/orbit_filter.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "run_tool.h"
#include "scene_files.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>

namespace phasecast::precompute {
namespace {

using testing::scratch_dir;
using testing::tiny_scene_path;

// An orbit store of N frames x = x0 + B c(t) with a known 3-dimensional motion subspace.
OrbitStore low_rank_store(const Scene& scene, int N) {
  OrbitStore s = empty_orbit_store(scene);
  const Eigen::Index M = 3 * scene.model.vertices();
  std::mt19937 rng(5);
  std::normal_distribution<float> g;
  Eigen::MatrixXf B(M, 3);
  for (Eigen::Index i = 0; i < B.size(); ++i) B.data()[i] = g(rng);
  s.positions.resize(N, M);
  for (int k = 0; k < N; ++k) {
    const float t = 0.02f * static_cast<float>(k);
    const Eigen::Vector3f c(std::sin(3 * t), 0.5f * std::cos(7 * t), 0.1f * std::sin(13 * t));
    s.positions.row(k) = s.rest_positions.reshaped<Eigen::RowMajor>().transpose() + (B * c).transpose();
  }
  s.velocities = MatrixXfR::Zero(N, M);
  s.support = MatrixXfR::Zero(N, core::kSupportFloats);
  s.frame_palette.assign(static_cast<size_t>(N), 0);
  // Two IRFs: entry close (0) for the first 400 frames, stop (1) after.
  s.irf_start = {0, 400};
  s.irf_length = {400, N - 400};
  s.irf_palette = {0, 1};
  s.irf_continues = {0, 1};
  std::fill(s.frame_palette.begin() + 400, s.frame_palette.end(), 1);
  return s;
}

class Reduction : public ::testing::Test {
 protected:
  Scene scene = load_scene_file(tiny_scene_path());
  PaletteRules rules = make_palette_rules(scene);

  // Why a package of the tiny scene is refused from an orbit store of `other`.
  std::string rejection_of_store_of(const Scene& other, const std::filesystem::path& dir) const {
    write_orbit_store(simulate_schedule(other, parse_schedule("open 0.1", other)), dir / "orbits.h5");
    const OrbitDisplacementSource A(dir / "orbits.h5");
    ReductionOptions ro;
    ro.max_rank = 3;
    const auto basis = reduce_displacements(A, ro);
    return testing::error_of<std::invalid_argument>(
        [&] { build_package(scene, rules, read_orbit_index(dir / "orbits.h5"), basis, {}); });
  }
};

TEST_F(Reduction, StreamedColumnsAreFramesMinusTheMeanAcrossBlocks) {
  const auto path = scratch_dir("reduce_stream") / "orbits.h5";
  const OrbitStore s = low_rank_store(scene, 700);  // more than one 512-frame block
  write_orbit_store(s, path);
  const OrbitDisplacementSource A(path);
  ASSERT_EQ(A.cols(), 700);
  ASSERT_EQ(A.rows(), s.positions.cols());
  const Eigen::VectorXf mean = s.positions.cast<double>().colwise().mean().transpose().cast<float>();
  EXPECT_LT((A.mean_shape() - mean).cwiseAbs().maxCoeff(), 1e-6f);
  Eigen::MatrixXf block;
  A.read(500, 100, block);
  const Eigen::MatrixXf expected = s.positions.middleRows(500, 100).transpose().colwise() - A.mean_shape();
  EXPECT_TRUE(block == expected);
}

TEST_F(Reduction, RankRuleFindsTheMotionSubspaceAndQuReconstructs) {
  const auto path = scratch_dir("reduce_rank") / "orbits.h5";
  const OrbitStore s = low_rank_store(scene, 600);
  write_orbit_store(s, path);
  const OrbitDisplacementSource A(path);
  ReductionOptions o;
  o.eps_u = 1e-3;
  o.max_rank = 10;
  const DisplacementBasis b = reduce_displacements(A, o);
  EXPECT_EQ(b.rank(), 3);
  EXPECT_EQ(b.singular_values.size(), 10);
  EXPECT_LT(b.rel_error(2), 1e-3f);
  EXPECT_GT(b.rel_error(1), 1e-2f);
  // u^k ~ U_u q_u^k (eq. 7), for every frame.
  const Eigen::MatrixXf rebuilt = (b.U_u * b.q_u.transpose()).colwise() + b.mean_shape;
  const Eigen::MatrixXf original = s.positions.transpose();
  EXPECT_LT((rebuilt - original).norm() / (original.colwise() - b.mean_shape).norm(), 1e-3f);
  // A fixed rank overrides eps_u and records eps_u = 0.
  o.rank = 2;
  const DisplacementBasis fixed = reduce_displacements(A, o);
  EXPECT_EQ(fixed.rank(), 2);
  EXPECT_EQ(fixed.eps_u, 0.0);
}

TEST_F(Reduction, BadOptionsAreRejectedWithOneLine) {
  const auto path = scratch_dir("reduce_bad_options") / "orbits.h5";
  write_orbit_store(low_rank_store(scene, 450), path);
  const OrbitDisplacementSource A(path);
  ReductionOptions o;
  o.eps_u = 1.5;
  try {
    reduce_displacements(A, o);
    FAIL() << "expected invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--eps-u in [0, 1), got 0, 60, 1.5"), std::string::npos) << e.what();
  }
}

TEST_F(Reduction, FileWithoutFramesIsRejectedNamingTheDataset) {
  const auto path = scratch_dir("reduce_no_frames") / "package.h5";
  core::write_package(testing::make_plate_package({}), path);
  try {
    const OrbitDisplacementSource A(path);
    FAIL() << "expected OrbitStoreError";
  } catch (const OrbitStoreError& e) {
    EXPECT_EQ(std::string(e.what()),
              path.string() + ": /frames/positions: missing dataset (expected N x 3V float32 frames)");
  }
  EXPECT_THROW(OrbitDisplacementSource(path.parent_path() / "nope.h5"), OrbitStoreError);
}

TEST(OrbitFilter, DropsShortIrfsAndDeadEnds) {
  // Four IRFs on a line: 0 and 1 loop near the origin, 2 is short, 3 ends far away.
  MatrixXfR q(9, 1);
  q << 0, 0.1f, 0.05f, 0.1f, 0.0f, 0.02f, 0.5f, 0.9f, 1.0f;
  const MatrixXfR qdot = MatrixXfR::Zero(9, 1);
  IrfList irfs;
  irfs.start = {0, 2, 4, 6};
  irfs.length = {2, 2, 1, 3};
  irfs.palette = {0, 1, 0, 1};
  OrbitFilterOptions o;
  o.min_frames = 2;
  o.dead_end_fraction = 0.3;  // radius 1: an end farther than 0.3 from every start is a dead end
  const auto r = filter_orbits(q, qdot, 1.0, irfs, o);
  EXPECT_EQ(r.kept, (std::vector<int>{0, 1}));
  EXPECT_EQ(r.dropped_short, 1);
  EXPECT_EQ(r.dropped_dead_end, 1);
  ASSERT_EQ(r.messages.size(), 2u);
  EXPECT_EQ(r.messages[0], "IRF 2 (entry 0): 1 nodes, shorter than the minimum 2");
  EXPECT_NE(r.messages[1].find(
                "IRF 3 (entry 1): dead end, last node 0.5 from the nearest IRF start (threshold 0.3"),
            std::string::npos)
      << r.messages[1];
  // Every IRF too short: each entry keeps its last one (the server refuses
  // entries without IRFs), its longest.
  o.min_frames = 5;
  o.dead_end_fraction = 0;
  const auto all_short = filter_orbits(q, qdot, 1.0, irfs, o);
  EXPECT_EQ(all_short.kept, (std::vector<int>{0, 3}));
  EXPECT_EQ(all_short.dropped_short, 2);
}

TEST_F(Reduction, SampledOrbitsBecomeAValidPackage) {
  const auto dir = scratch_dir("reduce_package");
  SamplingOptions so;
  so.chains = 2;
  so.irfs_per_chain = 3;
  so.work_dir = dir / "work";
  write_orbit_store(sample_irfs(scene, rules, so), dir / "orbits.h5");
  const OrbitDisplacementSource A(dir / "orbits.h5");
  ReductionOptions ro;
  ro.max_rank = 20;
  const auto basis = reduce_displacements(A, ro);
  const auto index = read_orbit_index(dir / "orbits.h5");
  PackageOptions po;
  po.filter.min_frames = 15;
  const auto built = build_package(scene, rules, index, basis, po);
  const auto& p = built.package;
  core::validate_package(p, "built");
  const int V = scene.model.vertices();
  const int door = p.mesh.points() - 2 * V;  // cloth front, cloth back, the door board as a tessellated box
  EXPECT_EQ(door, scene_mesh(scene).points() - 2 * V);
  EXPECT_GE(door, 24);
  EXPECT_EQ(std::count(p.mesh.deformable.begin(), p.mesh.deformable.end(), 1), 2 * V);
  EXPECT_EQ(p.reduction.U_u.bottomRows(3 * door).norm(), 0.0f);
  EXPECT_EQ(p.rank_u(), basis.rank());
  EXPECT_EQ(p.attributes.blend_lambda, kDefaultBlendLambda);
  EXPECT_GT(p.attributes.beta, 0.0);
  EXPECT_TRUE(p.palette.transitions == rules.transitions);
  // Every IRF shorter than 15 nodes was dropped and reported.
  int short_irfs = 0;
  for (auto len : index.irfs.length) short_irfs += len < 15;
  EXPECT_EQ(built.filter.dropped_short, short_irfs);
  EXPECT_EQ(p.portrait.irf_count() + short_irfs, 6);
  for (auto len : p.portrait.irf_length) EXPECT_GE(len, 15);
  // Eq. 8 at the last node of every IRF: backward difference.
  const int last = p.portrait.irf_start[0] + p.portrait.irf_length[0] - 1;
  const Eigen::RowVectorXf backward = (p.portrait.q_u.row(last) - p.portrait.q_u.row(last - 1)) / index.dt;
  EXPECT_LT((p.portrait.qdot_u.row(last) - backward).norm(), 1e-4f * (1 + backward.norm()));
  // From every IRF's start the cache plays an IRF of its entry starting at
  // about the same state (within 1 % of the portrait's radius), no shorter.
  const auto& pt = p.portrait;
  const double beta = p.attributes.beta;
  const auto phase = [&](int node) {
    Eigen::VectorXd x(2 * pt.q_u.cols());
    x << pt.q_u.row(node).cast<double>().transpose(),
        std::sqrt(beta) * pt.qdot_u.row(node).cast<double>().transpose();
    return x;
  };
  double radius = 0;
  for (int n = 0; n < pt.q_u.rows(); ++n) radius = std::max(radius, phase(n).norm());
  for (size_t i = 0; i < static_cast<size_t>(pt.irf_count()); ++i) {
    const auto j = static_cast<size_t>(pt.nearest_irf(pt.irf_start[i], pt.irf_palette[i]));
    EXPECT_EQ(pt.irf_palette[j], pt.irf_palette[i]);
    EXPECT_GE(pt.irf_length[j], pt.irf_length[i]) << "IRF " << i;
    EXPECT_LE((phase(pt.irf_start[j]) - phase(pt.irf_start[i])).norm(), 0.0101 * radius) << "IRF " << i;
  }
}

// Two descriptions that read alike are no help: the error names the palette's order.
TEST_F(Reduction, OrbitsOfAnotherPaletteOrderNameBothOrders) {
  const auto dir = scratch_dir("reduce_palette_order");
  std::string text = testing::read_file(testing::tiny_scene_path());
  for (auto at = text.find("\"close\""); at != std::string::npos; at = text.find("\"close\"", at))
    text.replace(at, 7, "\"shut\"");
  std::ofstream(dir / "shut.toml") << text;
  const auto error = rejection_of_store_of(load_scene_file(dir / "shut.toml"), dir);
  EXPECT_NE(error.find(": palette [shut, stop, open] in the store, [close, stop, open] in the "
                       "scene (names and order must match)"),
            std::string::npos)
      << error;
}

TEST_F(Reduction, OrbitsOfAnotherSceneAreRejected) {
  const auto dir = scratch_dir("reduce_mismatch");
  const auto error = rejection_of_store_of(
      load_scene_file(testing::edited_tiny_scene(dir, "cells = [5, 7]", "cells = [4, 7]")), dir);
  EXPECT_NE(error.find("orbit store of scene 'cloth_door_tiny' (40 vertices, 3 palette entries, "
                       "dt 0.02) does not belong to scene 'cloth_door_tiny': 40 vertices in the "
                       "store, 48 in the scene"),
            std::string::npos)
      << error;
}

}  // namespace
}  // namespace phasecast::precompute
