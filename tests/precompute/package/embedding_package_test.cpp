// Packages of scenes with render meshes (docs/scenes.md `render`): the tiny
// cloth subdivided once, its orbits simulated, reduced on the simulated
// vertices and embedded. What the server serves at a render point is the
// embedding of the reduced simulation, within the reduction error of the
// embedded simulation; without render meshes the rows are exact copies.

#include "phasecast/core/package.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/precompute/reduction/displacement_reduction.h"
#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/simulation/render_surface.h"
#include "run_tool.h"
#include "scene_files.h"
#include "source_tree.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <string>

namespace phasecast::precompute {
namespace {

using testing::run_tool;

struct Built {
  Scene scene;
  std::filesystem::path store;
  DisplacementBasis basis;
  core::ScenePackage package;
  MatrixXfR frames;  // N x 3V, as simulated
};

// Simulates a short schedule of `scene_path` into an orbit store in `dir`,
// reduces it at rank 6 and builds the package, every IRF kept (node n is frame n).
Built build(const std::filesystem::path& scene_path, const std::filesystem::path& dir,
            const std::string& schedule = "open 0.4; stop 0.6") {
  Built b;
  b.store = dir / "orbits.h5";
  const auto r = run_tool("phasecast-precompute",
                          {"simulate", scene_path.string(), "--schedule", schedule, "-o", b.store.string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  b.scene = load_scene_file(scene_path);
  const OrbitDisplacementSource A(b.store);
  ReductionOptions reduction;
  reduction.rank = 6;
  reduction.max_rank = 20;
  b.basis = reduce_displacements(A, reduction);
  PackageOptions options;
  options.filter.dead_end_fraction = 0;
  options.filter.min_frames = 1;
  b.package = build_package(b.scene, make_palette_rules(b.scene), read_orbit_index(b.store), b.basis, options)
                  .package;
  A.read_frames(0, A.cols(), b.frames);
  return b;
}

const Built& subdivided_cloth() {
  // ctest runs each test in its own process, several at once: one folder each.
  static const auto dir = testing::scratch_dir("embedded_package_" + std::to_string(::getpid()));
  static const Built b = build(
      testing::edited_tiny_scene(dir, "grid = { origin", "render = { subdivide = 1 }\ngrid = { origin"), dir);
  return b;
}

TEST(EmbeddedPackage, ScenePointsAreTheRenderMeshOnBothSidesThenTheDoor) {
  const Built& b = subdivided_cloth();
  const auto& m = b.package.mesh;
  const RenderSurface surface = render_surface(b.scene);
  const Eigen::Index P = surface.points(), V = b.scene.model.vertices();
  ASSERT_GT(P, V);  // finer than the simulated cloth
  int deformable = 0;
  for (auto d : m.deformable) deformable += d;
  EXPECT_EQ(deformable, 2 * P);  // a sheet: both sides
  const MatrixXfR rest = embed_rows(surface.weights, b.scene.model.rest.cast<float>());
  EXPECT_LT(
      (Eigen::Map<const MatrixXfR>(rest.data(), P, 3) - m.rest_positions.topRows(P)).cwiseAbs().maxCoeff(),
      1e-6f);
  EXPECT_EQ(b.package.reduction.U_u.rows(), 3 * m.points());
  // sigma and rel_error are those of the simulated displacements.
  EXPECT_TRUE(b.package.reduction.singular_values == b.basis.singular_values);
}

TEST(EmbeddedPackage, ServedRenderPointsAreTheEmbeddedRankRReconstruction) {
  const Built& b = subdivided_cloth();
  const auto& pkg = b.package;
  ASSERT_EQ(pkg.portrait.nodes(), b.frames.rows());  // nothing dropped: node n is frame n
  const VertexEmbedding W = scene_point_embedding(b.scene).weights;
  for (Eigen::Index f : {Eigen::Index{0}, Eigen::Index{12}, Eigen::Index{25}, b.frames.rows() - 1}) {
    const Eigen::VectorXf q = pkg.portrait.q_u.row(f).transpose();
    const Eigen::VectorXf served = pkg.reduction.mean_shape + pkg.reduction.U_u * q;
    const Eigen::VectorXf reduced =
        b.basis.mean_shape + b.basis.U_u * q;  // x-bar + U_u q_u of the simulation
    const MatrixXfR expected = embed_rows(W, reduced);
    double worst = 0;
    for (Eigen::Index p = 0; p < W.rows(); ++p)
      if (embeds(W, p))
        worst = std::max(
            worst,
            double((served.segment(3 * p, 3) - expected.col(0).segment(3 * p, 3)).cwiseAbs().maxCoeff()));
    EXPECT_LT(worst, 2e-6) << "frame " << f;
    // Loop's weights are convex: a render point is off by no more than the
    // reduction is off at the simulated vertices.
    const Eigen::VectorXf truth = b.frames.row(f).transpose();
    const MatrixXfR embedded_truth = embed_rows(W, truth);
    const double reduction_error = (reduced - truth).cwiseAbs().maxCoeff();
    double off = 0;
    for (Eigen::Index p = 0; p < W.rows(); ++p)
      if (embeds(W, p))
        off = std::max(
            off,
            double(
                (served.segment(3 * p, 3) - embedded_truth.col(0).segment(3 * p, 3)).cwiseAbs().maxCoeff()));
    EXPECT_LE(off, reduction_error + 2e-6) << "frame " << f;
    EXPECT_GT(off, 0.0);  // rank 6 is not exact: the bound is not vacuous
  }
  // Static door points stay at rest with zero rows.
  EXPECT_TRUE(pkg.reduction.U_u.bottomRows(3).isZero());
}

TEST(EmbeddedPackage, InspectAcceptsTheReducedPackage) {
  const Built& b = subdivided_cloth();
  const auto pkg = (b.store.parent_path() / "cli.h5").string();
  const auto scene = (b.store.parent_path() / "scene.toml").string();
  const auto r = run_tool("phasecast-precompute", {"reduce", scene, b.store.string(), "-o", pkg,
                                                   "--no-appearance", "--max-rank", "20"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto inspect = run_tool("phasecast-inspect", {pkg});
  ASSERT_EQ(inspect.exit_code, 0) << inspect.err;
  const int P = static_cast<int>(render_surface(b.scene).points());
  EXPECT_NE(inspect.out.find(fmt::format("({} deformable)", 2 * P)), std::string::npos) << inspect.out;
}

// The tiny plant, its stem drawn as an octagonal tube (radius 4 mm).
const Built& tubed_plant() {
  static const Built b =
      build(phasecast::testing::scenes_dir() / "tiny/plant_pot.toml",
            testing::scratch_dir("tubed_package_" + std::to_string(::getpid())), "right 0.4; stop 0.6");
  return b;
}

TEST(EmbeddedPackage, ATubeIsServedAroundTheServedStem) {
  const Built& b = tubed_plant();
  const auto& pkg = b.package;
  const RenderSurface surface = render_surface(b.scene);
  const Embedding E = scene_point_embedding(b.scene);
  ASSERT_FALSE(surface.offsets.empty());
  // At rest the package's rings are the stem's vertices plus their offsets, one-sided.
  int deformable = 0;
  for (auto d : pkg.mesh.deformable) deformable += d;
  int tube = 0;
  for (auto t : surface.tube) tube += t;
  EXPECT_EQ(deformable, 2 * (surface.points() - tube) + tube);  // the leaves both sides, the tube one
  for (const auto& [p, d] : surface.offsets) {
    const Eigen::Index v = VertexEmbedding::InnerIterator(surface.weights, p).col();
    const Eigen::Vector3d at = pkg.mesh.rest_positions.row(p).cast<double>().transpose();
    EXPECT_LT((at - b.scene.model.rest.segment<3>(3 * v) - d).norm(), 1e-6);
  }
  // Served, a ring point is the served axis vertex plus its rest offset: x-bar + d, then U_u q.
  for (Eigen::Index f : {Eigen::Index{0}, Eigen::Index{20}, b.frames.rows() - 1}) {
    const Eigen::VectorXf q = pkg.portrait.q_u.row(f).transpose();
    const Eigen::VectorXf served = pkg.reduction.mean_shape + pkg.reduction.U_u * q;
    const Eigen::VectorXf reduced = b.basis.mean_shape + b.basis.U_u * q;
    for (const auto& [p, d] : surface.offsets) {
      const Eigen::Index v = VertexEmbedding::InnerIterator(surface.weights, p).col();
      const Eigen::Vector3f axis = reduced.segment<3>(3 * v);
      EXPECT_LT((served.segment<3>(3 * p) - axis - d.cast<float>()).cwiseAbs().maxCoeff(), 2e-6f)
          << "frame " << f << " point " << p;
    }
  }
  // The stem swayed: the check is not of a still scene.
  const Eigen::Index v = VertexEmbedding::InnerIterator(surface.weights, surface.offsets.back().point).col();
  double sway = 0;
  for (Eigen::Index f = 0; f < b.frames.rows(); ++f)
    sway = std::max(sway,
                    double((b.frames.row(f).segment<3>(3 * v) - b.frames.row(0).segment<3>(3 * v)).norm()));
  EXPECT_GT(sway, 0.01);
  EXPECT_EQ(E.offsets.size(), surface.offsets.size());
}

// Bit for bit, -0 included: the package rows of a scene without render meshes.
bool same_bits(const float* a, const float* b, Eigen::Index n) {
  return std::memcmp(a, b, sizeof(float) * static_cast<size_t>(n)) == 0;
}

TEST(EmbeddedPackage, WithoutRenderMeshesRowsAreExactCopiesOfTheSimulatedVertices) {
  const Built b = build(testing::tiny_scene_path(), testing::scratch_dir("plain_package"));
  const auto& r = b.package.reduction;
  const Eigen::Index V = b.scene.model.vertices(), r_u = b.basis.rank();
  const MatrixXfR U = b.basis.U_u;  // row-major, as the package
  const Eigen::VectorXf rest = b.scene.model.rest.cast<float>();
  // Front points are the vertices, the back side (every cloth vertex) copies them.
  for (Eigen::Index side = 0; side < 2; ++side) {
    EXPECT_TRUE(same_bits(r.mean_shape.data() + 3 * V * side, b.basis.mean_shape.data(), 3 * V)) << side;
    EXPECT_TRUE(same_bits(r.U_u.data() + 3 * V * r_u * side, U.data(), 3 * V * r_u)) << side;
    EXPECT_TRUE(same_bits(b.package.mesh.rest_positions.data() + 3 * V * side, rest.data(), 3 * V)) << side;
  }
}

}  // namespace
}  // namespace phasecast::precompute
