// A body's `render` mesh in scene files: what the scene shows instead of the
// simulated surface (render_surface), the simulation left as it was, and a
// one-line error naming the field for every bad value.

#include "error_of.h"
#include "phasecast/precompute/simulation/obj_mesh.h"
#include "phasecast/precompute/simulation/render_surface.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "run_tool.h"
#include "source_tree.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <map>
#include <string>

namespace phasecast::precompute {
namespace {

using phasecast::testing::error_of;

const std::filesystem::path kScenes = phasecast::testing::scenes_dir();

// The shipped tiny scene `name` with `from` replaced by `to`, written to a scratch folder.
std::filesystem::path edited_scene(const std::string& name, const std::string& from, const std::string& to,
                                   const std::string& test) {
  std::string text = testing::read_file(kScenes / "tiny" / (name + ".toml"));
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  const auto path = testing::scratch_dir("render_" + test) / "scene.toml";
  std::ofstream(path) << text;
  return path;
}

const std::string kClothGrid = "grid = { origin";
const std::string kStemTube = "render = { tube = 8 }";  // the tiny plant's stem
const std::string kToyMesh = "tetgen = { path = \"../meshes/bunny_tiny.obj\"";
std::string toy_mesh() {
  return "tetgen = { path = \"" + (kScenes / "meshes/bunny_tiny.obj").string() + "\"";
}

// The render points at rest: W X.
Eigen::MatrixX3d render_rest(const Scene& s, const RenderSurface& r) {
  const Eigen::MatrixX3d X = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      s.model.rest.data(), s.model.vertices(), 3);
  return Eigen::MatrixXd(r.weights) * X;
}

TEST(RenderSurface, WithoutRenderMeshesItIsTheSimulatedSurface) {
  const Scene s = load_scene_file(kScenes / "tiny/cloth_door.toml");
  const RenderSurface r = render_surface(s);
  const VertexEmbedding I = Eigen::MatrixXd::Identity(s.model.vertices(), s.model.vertices()).sparseView();
  EXPECT_EQ(Eigen::MatrixXd(r.weights), Eigen::MatrixXd(I));
  EXPECT_EQ(r.triangles, s.model.surface);
}

TEST(RenderSurface, SubdividedClothReplacesTheSimulatedSurfaceAndLeavesTheSimulationAlone) {
  const Scene plain = load_scene_file(kScenes / "tiny/cloth_door.toml");
  const Scene s = load_scene_file(edited_scene(
      "cloth_door", kClothGrid, "render = { subdivide = 1 }\n" + kClothGrid, "cloth_subdivided"));
  EXPECT_EQ(s.model.rest, plain.model.rest);
  EXPECT_EQ(s.model.mass, plain.model.mass);
  EXPECT_EQ(s.model.surface, plain.model.surface);
  const RenderSurface r = render_surface(s);
  const auto edges = static_cast<Eigen::Index>(surface_edges(plain.model.surface).size());
  ASSERT_EQ(r.points(), 48 + edges);  // one point per vertex and per edge
  EXPECT_EQ(r.triangles.rows(), 4 * plain.model.surface.rows());
  EXPECT_EQ(r.triangles.maxCoeff(), r.points() - 1);
  // The cloth is a flat 0.5 x 0.7 m sheet at z = 0.012: so is its render mesh.
  const Eigen::MatrixX3d x = render_rest(s, r);
  EXPECT_LT((x.col(2).array() - 0.012).abs().maxCoeff(), 1e-12);
  EXPECT_GE(x.col(0).minCoeff(), 0.2 - 1e-12);
  EXPECT_LE(x.col(0).maxCoeff(), 0.7 + 1e-12);
  EXPECT_GE(x.col(1).minCoeff(), 1.15 - 1e-12);
  EXPECT_LE(x.col(1).maxCoeff(), 1.85 + 1e-12);
  for (size_t p = 0; p < r.body.size(); ++p) {
    EXPECT_EQ(r.body[p], 0);
    EXPECT_EQ(r.solid[p], 0);  // a sheet: the package gives it a back side
  }
}

TEST(RenderSurface, ObjInsideTheToyMovesWithItsTets) {
  const Scene s = load_scene_file(edited_scene(
      "toy_dashboard", kToyMesh,
      "render = { obj = \"" + (kScenes / "meshes/bunny_tiny.obj").string() + "\" }\n" + toy_mesh(),
      "toy_obj"));
  const ObjMesh fine = read_obj(kScenes / "meshes/bunny_tiny.obj");
  const RenderSurface r = render_surface(s);
  ASSERT_EQ(r.points(), fine.vertices.rows());
  EXPECT_LT((render_rest(s, r) - fine.vertices).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(r.triangles, Eigen::MatrixXi(fine.triangles));
  for (auto solid : r.solid) EXPECT_EQ(solid, 1);  // a solid's boundary: single-sided
}

TEST(RenderSurface, RenderedLeavesKeepTheStemTheyAreWeldedTo) {
  std::string text = testing::read_file(kScenes / "tiny/plant_pot.toml");
  text.erase(text.find(kStemTube), kStemTube.size());  // the stem shown as simulated
  const std::string weld = "weld_to = \"stem\"", render = "render = { subdivide = 1 }\n";
  for (size_t at = 0; (at = text.find(weld, at)) != std::string::npos; at += render.size() + weld.size())
    text.insert(at, render);
  const auto path = testing::scratch_dir("render_leaves") / "scene.toml";
  std::ofstream(path) << text;
  const Scene s = load_scene_file(path);
  const RenderSurface r = render_surface(s);
  const auto& stem = s.bodies.at(0).vertices;
  bool welded = false;  // some leaf point moves with a stem vertex
  for (Eigen::Index p = 0; p < r.points(); ++p) {
    if (p < static_cast<Eigen::Index>(stem.size())) {
      EXPECT_EQ(r.weights.coeff(p, stem[static_cast<size_t>(p)]), 1.0);  // the rod as simulated
      continue;
    }
    EXPECT_GT(r.body[static_cast<size_t>(p)], 0);
    for (VertexEmbedding::InnerIterator it(r.weights, p); it; ++it)
      welded |= std::find(stem.begin(), stem.end(), it.col()) != stem.end();
  }
  EXPECT_TRUE(welded);
}

// The tiny plant's stem (a straight rod of radius 4 mm, 8 vertices up the
// y axis) drawn as a tube of `sides`.
Scene tubed_plant(int sides, const std::string& test) {
  return load_scene_file(
      edited_scene("plant_pot", kStemTube, fmt::format("render = {{ tube = {} }}", sides), test));
}

TEST(RenderSurface, ATubeDrawsTheRodAtItsRadiusAroundEachVertex) {
  const Scene plain = load_scene_file(edited_scene("plant_pot", kStemTube, "", "untubed"));
  const Scene s = tubed_plant(6, "tube");
  EXPECT_EQ(s.model.rest, plain.model.rest);  // the simulation is left alone
  EXPECT_EQ(s.model.mass, plain.model.mass);
  const RenderSurface r = render_surface(s);
  const auto& stem = s.bodies.at(0).vertices;
  const auto n = static_cast<Eigen::Index>(stem.size());
  // The stem's vertices the leaves are not welded to are no longer points of their own.
  Eigen::Index tube_points = 0;
  for (auto t : r.tube) tube_points += t;
  ASSERT_EQ(tube_points, 6 * n + 2);  // a ring per vertex and two cap centres
  ASSERT_EQ(static_cast<Eigen::Index>(r.offsets.size()), 6 * n);
  const Eigen::MatrixX3d x = render_rest(s, r);  // W X, offsets not yet added
  for (const auto& [p, d] : r.offsets) {
    ASSERT_TRUE(r.tube[static_cast<size_t>(p)]);
    EXPECT_EQ(r.solid[static_cast<size_t>(p)], 1);  // closed: no back side
    // One weight, 1, on the axis vertex: the ring moves as its vertex does.
    ASSERT_EQ(r.weights.row(p).nonZeros(), 1);
    EXPECT_EQ(r.weights.row(p).sum(), 1.0);
    EXPECT_NEAR(d.norm(), 0.004, 1e-12);  // at the rod's radius
    EXPECT_NEAR(d.y(), 0.0, 1e-12);       // across the vertical stem
    EXPECT_NEAR(x(p, 0), 0.0, 1e-12);     // around the stem's axis
    EXPECT_NEAR(x(p, 2), 0.0, 1e-12);
  }
  // Closed and facing out: every edge is in two triangles, once each way,
  // and the enclosed volume is a hexagonal prism's, (3 sqrt 3 / 2) r^2 L.
  const Eigen::MatrixXi tubes = r.triangles.bottomRows(12 * n);
  const MatrixXfR placed = embed_positions(r.embedding(), s.model.rest.cast<float>());
  std::map<std::pair<int, int>, int> edges;
  double volume = 0;
  for (Eigen::Index t = 0; t < tubes.rows(); ++t) {
    for (int k = 0; k < 3; ++k) ++edges[{tubes(t, k), tubes(t, (k + 1) % 3)}];
    const auto corner = [&](int k) -> Eigen::Vector3d {
      return placed.middleRows(3 * tubes(t, k), 3).col(0).cast<double>();
    };
    volume += corner(0).dot(corner(1).cross(corner(2))) / 6;
  }
  for (const auto& [edge, count] : edges) {
    EXPECT_EQ(count, 1);
    EXPECT_EQ(edges.count({edge.second, edge.first}), 1u);
  }
  EXPECT_NEAR(volume, 1.5 * std::sqrt(3.0) * 0.004 * 0.004 * 0.35, 1e-9);
  // Self-contact sees the rod as a line: the tube stays out of the contact check.
  EXPECT_EQ(contact_triangles(r).rows(), r.triangles.rows() - tubes.rows());
  EXPECT_EQ(contact_triangles(r), r.triangles.topRows(r.triangles.rows() - tubes.rows()));
}

// A rod with three right-angle corners in different planes (the tiny plant's
// stem bent into a crank): each ring halves its corner's angle, and the
// frame carried from ring to ring never flips, so the tube stays closed,
// outward and unpinched.
TEST(RenderSurface, ATubeFollowsSharpBendsWithoutFlippingItsRings) {
  const Scene s = load_scene_file(edited_scene(
      "plant_pot", "points = [[0, 0.12, 0], [0, 0.47, 0]], subdivisions = 7",
      "points = [[0, 0.12, 0], [0, 0.3, 0], [0.1, 0.3, 0], [0.1, 0.3, 0.1], [0.1, 0.2, 0.1]]", "crank"));
  const RenderSurface r = render_surface(s);
  const auto& stem = s.bodies.at(0).vertices;
  ASSERT_EQ(stem.size(), 5u);
  const int k = 8;
  const MatrixXfR placed = embed_positions(r.embedding(), s.model.rest.cast<float>());
  const auto X = [&](int i) -> Eigen::Vector3d {
    return s.model.rest.segment<3>(3 * stem[static_cast<size_t>(i)]);
  };
  // The tube's points: the last 5 k + 2 of the surface, ring i then the caps.
  const Eigen::Index first = r.points() - (5 * k + 2);
  const auto ring_offset = [&](int i, int j) -> Eigen::Vector3d {
    return placed.middleRows(3 * (first + k * i + j), 3).col(0).cast<double>() - X(i);
  };
  for (int i = 0; i < 5; ++i) {
    Eigen::Vector3d t = Eigen::Vector3d::Zero();  // the bisector of the edges at vertex i
    if (i > 0) t += (X(i) - X(i - 1)).normalized();
    if (i < 4) t += (X(i + 1) - X(i)).normalized();
    t.normalize();
    for (int j = 0; j < k; ++j) {
      EXPECT_NEAR(ring_offset(i, j).norm(), 0.004, 1e-6);
      EXPECT_NEAR(ring_offset(i, j).dot(t), 0.0, 1e-6) << "ring " << i << " is not across its bisector";
      // Point j of the next ring lies on the same side: no flip, no pinch.
      if (i < 4) {
        EXPECT_GT(ring_offset(i, j).dot(ring_offset(i + 1, j)), 0.0) << "rings " << i << ", " << i + 1;
      }
    }
  }
  std::map<std::pair<int, int>, int> edges;
  double volume = 0;
  for (Eigen::Index t = 0; t < r.triangles.rows(); ++t) {
    if (!r.tube[static_cast<size_t>(r.triangles(t, 0))]) continue;
    const auto corner = [&](int c) -> Eigen::Vector3d {
      return placed.middleRows(3 * r.triangles(t, c), 3).col(0).cast<double>();
    };
    for (int c = 0; c < 3; ++c) ++edges[{r.triangles(t, c), r.triangles(t, (c + 1) % 3)}];
    volume += corner(0).dot(corner(1).cross(corner(2))) / 6;
  }
  for (const auto& [edge, count] : edges) EXPECT_EQ(count + edges.count({edge.second, edge.first}), 2u);
  // Outward, and near a straight tube's volume over the rod's 0.48 m: the
  // rings at the corners are not mitred (radius r in the bisecting plane, so
  // r cos 45 deg across the edges), and the tube narrows there (measured 0.79).
  const double straight = 0.5 * k * std::sin(2 * std::acos(-1.0) / k) * 0.004 * 0.004 * 0.48;
  EXPECT_GT(volume, 0.7 * straight);
  EXPECT_LT(volume, 1.05 * straight);
}

TEST(RenderSurface, ATubeRidesOnItsVerticesWithoutTurning) {
  const Scene s = tubed_plant(5, "tube_moved");
  const RenderSurface r = render_surface(s);
  // The stem bent into an arc: each vertex moved on its own.
  Eigen::VectorXd x = s.model.rest;
  for (int v = 0; v < s.model.vertices(); ++v) {
    const double y = x(3 * v + 1);
    x.segment<3>(3 * v) += Eigen::Vector3d(0.3 * y * y, -0.05 * y, 0.1 * y);
  }
  const MatrixXfR placed = embed_positions(r.embedding(), x.cast<float>());
  for (const auto& [p, d] : r.offsets) {
    const Eigen::Index axis = VertexEmbedding::InnerIterator(r.weights, p).col();
    const Eigen::Vector3d at = placed.middleRows(3 * p, 3).col(0).cast<double>();
    EXPECT_LT((at - x.segment<3>(3 * axis) - d).norm(), 1e-6);  // the vertex plus the rest offset
  }
}

// The message after the file name, checked to be one line naming the file.
std::string rejection(const std::filesystem::path& path) {
  const std::string message = error_of([&] { load_scene_file(path); });
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  EXPECT_EQ(message.rfind(path.string(), 0), 0u) << message;
  return message.substr(std::min(message.size(), path.string().size()));
}

std::string cloth_rejection(const std::string& render, const std::string& test) {
  return rejection(edited_scene("cloth_door", kClothGrid, render + "\n" + kClothGrid, test));
}

TEST(RenderErrors, BadValuesNameTheKeyAndWhatWasExpected) {
  EXPECT_EQ(cloth_rejection("render = { subdivide = 0 }", "zero"),
            ": field 'body[0].render.subdivide': expected a positive integer, got integer 0");
  EXPECT_EQ(cloth_rejection("render = { subdivide = 6 }", "six"),
            ": field 'body[0].render.subdivide': expected a subdivision level in 1..5 (each level has 4x the "
            "triangles), got integer 6");
  EXPECT_EQ(cloth_rejection("render = { subdivide = \"two\" }", "string"),
            ": field 'body[0].render.subdivide': expected a positive integer, got string \"two\"");
  EXPECT_EQ(cloth_rejection("render = 2", "number"),
            ": field 'body[0].render': expected a table, got integer 2");
  EXPECT_EQ(
      cloth_rejection("render = {}", "empty"),
      ": field 'body[0].render.subdivide': expected one of subdivide = n (Loop subdivision of the "
      "simulated surface), obj = \"fine.obj\" (a surface inside a tetgen body) or tube = k (a rod drawn as a "
      "tube of k sides), got nothing (missing)");
  EXPECT_NE(cloth_rejection("render = { subdivide = 1, obj = \"a.obj\" }", "both")
                .find(": field 'body[0].render.obj': expected one of subdivide = n"),
            std::string::npos);
  EXPECT_EQ(cloth_rejection("render = { subdivide = 1, smooth = true }", "unknown"),
            ": field 'body[0].render.smooth': unknown field (expected one of obj, subdivide, tube)");
  EXPECT_EQ(
      cloth_rejection("render = { obj = \"a.obj\" }", "obj_on_sheet"),
      ": field 'body[0].render.obj': expected a tetgen body (a render OBJ moves with the tets around it; "
      "sheets use subdivide), got string \"a.obj\"");
}

TEST(RenderErrors, ARodHasNoSurfaceToSubdivide) {
  EXPECT_EQ(
      rejection(edited_scene("plant_pot", kStemTube, "render = { subdivide = 1 }", "rod")),
      ": field 'body[0].render.subdivide': expected a body with a triangle surface (grid, obj or tetgen) "
      "to subdivide, got integer 1");
}

TEST(RenderErrors, ATubeIsForARodOfOnePolyline) {
  EXPECT_EQ(
      cloth_rejection("render = { tube = 6 }", "tube_on_sheet"),
      ": field 'body[0].render.tube': expected a rod body (a polyline with 'rod' energy and a radius) to "
      "draw as a tube, got integer 6");
  EXPECT_EQ(rejection(edited_scene("plant_pot", kStemTube, "render = { tube = 2 }", "tube2")),
            ": field 'body[0].render.tube': expected the sides of the tube's rings, 3..32, got integer 2");
  EXPECT_EQ(rejection(edited_scene("plant_pot", kStemTube, "render = { tube = 33 }", "tube33")),
            ": field 'body[0].render.tube': expected the sides of the tube's rings, 3..32, got integer 33");
  EXPECT_NE(rejection(edited_scene("plant_pot", kStemTube, "render = { tube = 6, subdivide = 1 }",
                                   "tube_and_subdivide"))
                .find(": field 'body[0].render.tube': expected one of subdivide = n"),
            std::string::npos);
}

TEST(RenderErrors, AnObjOutsideTheTetsIsRefused) {
  // The 240-vertex bunny around the 60-vertex one's tets: its ears stick out by 11 mm.
  const std::string message = rejection(
      edited_scene("toy_dashboard", kToyMesh,
                   "render = { obj = \"" + (kScenes / "meshes/bunny.obj").string() + "\" }\n" + toy_mesh(),
                   "toy_outside"));
  EXPECT_EQ(message.rfind(": field 'body[0].render.obj': render vertex ", 0), 0u) << message;
  EXPECT_NE(message.find(" outside the tets (expected within 0.00"), std::string::npos) << message;
  EXPECT_NE(message.find("mesh the tets from a surface that encloses the render mesh"), std::string::npos)
      << message;
  const std::string missing = rejection(edited_scene(
      "toy_dashboard", kToyMesh, "render = { obj = \"no_such.obj\" }\n" + toy_mesh(), "toy_missing"));
  EXPECT_EQ(missing.rfind(": field 'body[0].render.obj': ", 0), 0u) << missing;
  EXPECT_NE(missing.find("no_such.obj"), std::string::npos) << missing;
}

}  // namespace
}  // namespace phasecast::precompute
