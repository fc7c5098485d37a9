// Contact: the exact triangle-triangle test, self-collision keeping sheets
// apart, and the measured guarantee on cloth_door: no intersecting triangle
// pairs in any recorded frame of a long run.

#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "run_tool.h"
#include "source_tree.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

namespace phasecast::precompute {
namespace {

const std::filesystem::path kScenes = phasecast::testing::scenes_dir();
using Eigen::Vector3d;

TEST(TriangleIntersection, CrossingAndSeparatedPairs) {
  const std::array<Vector3d, 3> flat = {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)};
  const std::array<Vector3d, 3> piercing = {Vector3d(0.2, 0.2, -1), Vector3d(0.3, 0.2, 1),
                                            Vector3d(0.2, 0.3, 1)};
  const std::array<Vector3d, 3> above = {Vector3d(0.2, 0.2, 0.01), Vector3d(0.3, 0.2, 1),
                                         Vector3d(0.2, 0.3, 1)};
  const std::array<Vector3d, 3> beside = {Vector3d(0.6, 0.6, -1), Vector3d(0.9, 0.6, 1),
                                          Vector3d(0.6, 0.9, 1)};
  EXPECT_TRUE(triangles_intersect(flat, piercing));
  EXPECT_TRUE(triangles_intersect(piercing, flat));
  EXPECT_FALSE(triangles_intersect(flat, above));
  EXPECT_FALSE(triangles_intersect(flat, beside));  // crosses the plane outside the triangle
}

// Two parallel sheets 5 cm apart; the upper one is thrown through the lower one.
Scene two_sheets(bool self_collision) {
  const std::string text = R"(name = "sheets"
[simulation]
frame_dt = 0.01
substeps = 2
gravity = [0, 0, 0]
[support]
motion = "translational"
axis = [1, 0, 0]
[contact]
thickness = 0.01
self_collision = )" + std::string(self_collision ? "true" : "false") +
                           R"(
[[body]]
name = "lower"
energies = ["membrane", "bending"]
density = 0.2
young = 200
bending = 1e-5
grid = { origin = [0, 0, 0], u = [0.4, 0, 0], v = [0, 0, 0.4], cells = [6, 6] }
pin = { min = [-0.01, -0.01, -0.01], max = [0.41, 0.01, 0.01] }
[[body]]
name = "upper"
energies = ["membrane", "bending"]
density = 0.2
young = 200
bending = 1e-5
grid = { origin = [0.1, 0.05, 0.1], u = [0.2, 0, 0], v = [0, 0, 0.2], cells = [3, 3] }
[[palette]]
name = "none"
alpha_impulse = [0, 0, 0]
alpha_forcing = [0, 0, 0]
)";
  const auto path = testing::scratch_dir(self_collision ? "sheets_on" : "sheets_off") / "sheets.toml";
  std::ofstream(path) << text;
  return load_scene_file(path);
}

struct SheetOutcome {
  int worst_intersections = 0;
  double upper_y = 0;        // mean height of the thrown sheet at the end
  double lower_under_y = 0;  // mean height of the lower sheet's vertices under its footprint
};

SheetOutcome throw_sheet(bool self_collision) {
  const Scene scene = two_sheets(self_collision);
  auto sim = make_simulator(scene);
  SimState s = sim->rest_state();
  for (int v : scene.bodies[1].vertices) s.v[3 * v + 1] = -3.0;  // 3 m/s down onto the lower sheet
  sim->reset(s);
  SheetOutcome out;
  for (int i = 0; i < 30; ++i) {
    sim->step(Eigen::Vector3d::Zero());
    out.worst_intersections =
        std::max(out.worst_intersections, count_intersecting_pairs(sim->state().x, scene.model.surface));
  }
  const auto& x = sim->state().x;
  for (int v : scene.bodies[1].vertices)
    out.upper_y += x[3 * v + 1] / static_cast<double>(scene.bodies[1].vertices.size());
  int under = 0;
  for (int v : scene.bodies[0].vertices) {
    const double px = scene.model.rest[3 * v], pz = scene.model.rest[3 * v + 2];
    if (px > 0.1 && px < 0.3 && pz > 0.1 && pz < 0.3) out.lower_under_y += x[3 * v + 1], ++under;
  }
  out.lower_under_y /= under;
  return out;
}

// The close count measures the colliding surface: a vertex of no triangle
// (a rod's, a stem frame's point at the end of a brace) numbered among the
// surface's vertices is not one of its points, however near a leaf it lies.
TEST(ContactSummary, OnlySurfaceVerticesCountAsClose) {
  Eigen::MatrixXi triangles(2, 3);
  triangles << 0, 1, 2, 4, 5, 6;  // vertex 3 is on no triangle
  const double gap = 0.01;        // between the two triangles, m
  const std::vector<Vector3d> points = {Vector3d(0, 0, 0),     Vector3d(0.1, 0, 0), Vector3d(0, 0.1, 0),
                                        Vector3d(0.001, 0, 0), Vector3d(0, 0, gap), Vector3d(0.1, 0, gap),
                                        Vector3d(0, 0.1, gap)};
  MatrixXfR frames(1, 3 * static_cast<Eigen::Index>(points.size()));
  for (std::size_t v = 0; v < points.size(); ++v)
    for (int c = 0; c < 3; ++c)
      frames(0, 3 * static_cast<Eigen::Index>(v) + c) = static_cast<float>(points[v][c]);
  const ContactSummary wide = summarize_contact(frames, triangles, 0.02, 0.01);
  EXPECT_EQ(wide.frames_close, 1);
  EXPECT_NEAR(wide.closest, gap, 1e-6) << "vertex 3, 1 mm from vertex 0, does not count";
  EXPECT_EQ(summarize_contact(frames, triangles, 0.005, 0.0025).frames_close, 0);
}

// Contact is where the self-collision acts: a vertex held at the thickness
// from a triangle's face, however far from that triangle's vertices.
TEST(ContactSummary, AVertexHeldAtTheThicknessOverAFaceIsInContact) {
  Eigen::MatrixXi triangles(2, 3);
  triangles << 0, 1, 2, 3, 4, 5;
  const double thickness = 0.003;
  const auto frame_at = [](double gap) {
    // vertex 3 over the middle of triangle 0, 5 cm from its corners
    const std::vector<Vector3d> points = {Vector3d(0, 0, 0),        Vector3d(0.15, 0, 0),
                                          Vector3d(0, 0.15, 0),     Vector3d(0.05, 0.05, gap),
                                          Vector3d(0.2, 0.05, gap), Vector3d(0.05, 0.2, gap)};
    MatrixXfR frame(1, 18);
    for (int v = 0; v < 6; ++v)
      for (int c = 0; c < 3; ++c) frame(0, 3 * v + c) = static_cast<float>(points[static_cast<size_t>(v)][c]);
    return frame;
  };
  const ContactSummary held = summarize_contact(frame_at(thickness), triangles, 2 * thickness, thickness);
  EXPECT_EQ(held.frames_in_contact, 1);
  EXPECT_NEAR(held.closest_to_triangle, thickness, 1e-6);
  EXPECT_EQ(held.frames_close, 0) << "no two vertices are within twice the thickness";
  const ContactSummary apart =
      summarize_contact(frame_at(1.5 * thickness), triangles, 2 * thickness, thickness);
  EXPECT_EQ(apart.frames_in_contact, 0);
  EXPECT_NEAR(apart.closest_to_triangle, 1.5 * thickness, 1e-6);
  EXPECT_FALSE(std::isfinite(
      summarize_contact(frame_at(3 * thickness), triangles, 2 * thickness, thickness).closest_to_triangle))
      << "nothing within twice the thickness";
}

TEST(SelfCollision, WithoutItASheetPassesThroughAnother) {
  const auto o = throw_sheet(false);
  EXPECT_LT(o.upper_y, o.lower_under_y);
}

TEST(SelfCollision, ProximityRepulsionKeepsSheetsApart) {
  const auto o = throw_sheet(true);
  EXPECT_GT(o.upper_y, o.lower_under_y);  // it carried the lower sheet along instead
  EXPECT_EQ(o.worst_intersections, 0);
}

// A small free triangle 5 mm over a large pinned one (thickness 10 mm, h =
// 10 ms), sliding at 1 m/s and closing at 0.5 m/s. Repulsion (Bridson et al.
// 2002) turns the normal velocity to the 0.5 m/s that restores the thickness
// in one step, a change of 1 m/s; Coulomb friction takes mu x 1 m/s off the
// 1 m/s slide: 0.7 m/s at mu = 0.3, and stops it (not reverses) at mu = 2.
Eigen::VectorXd slide_over_pinned_triangle(double friction) {
  Eigen::MatrixXi triangles(2, 3);
  triangles << 0, 1, 2, 3, 4, 5;
  const double d0 = 0.005;
  Eigen::VectorXd x0(18), v = Eigen::VectorXd::Zero(18), inverse_mass(6);
  x0 << -1, -1, 0, 2, -1, 0, -1, 2, 0, 0, 0, d0, 0.1, 0, d0, 0, 0.1, d0;
  inverse_mass << 0, 0, 0, 1, 1, 1;
  for (int i = 3; i < 6; ++i) v.segment<3>(3 * i) = Vector3d(1, 0, -0.5);
  SelfCollision(triangles, 0.01, friction).filter(x0, v, 0.01, inverse_mass);
  return v;
}

TEST(SelfCollision, FrictionTakesCoulombsShareOffTheSlide) {
  for (const auto& [mu, slide] : {std::pair{0.0, 1.0}, std::pair{0.3, 0.7}, std::pair{2.0, 0.0}}) {
    const Eigen::VectorXd v = slide_over_pinned_triangle(mu);
    for (int i = 3; i < 6; ++i) {
      EXPECT_NEAR(v[3 * i], slide, 1e-12) << "mu = " << mu << ", vertex " << i;
      EXPECT_NEAR(v[3 * i + 1], 0, 1e-12);
      EXPECT_NEAR(v[3 * i + 2], 0.5, 1e-12) << "the normal response does not depend on friction";
    }
    EXPECT_EQ(v.head<9>(), Eigen::VectorXd::Zero(9)) << "pinned vertices never move";
  }
}

// A vertex closing on a free triangle of unequal masses, at a point inside it
// (barycentric weights 0.2, 0.3, 0.5): the same Coulomb share comes off the
// relative slide, whatever the weights and masses, and the impulses are
// internal, so momentum is conserved.
TEST(SelfCollision, FrictionActsOnTheRelativeSlideAndConservesMomentum) {
  Eigen::MatrixXi triangles(2, 3);
  triangles << 0, 1, 2, 3, 4, 5;
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), w(0.2, 0.3, 0.5);
  const double d0 = 0.004, mu = 0.25;
  Eigen::VectorXd x0(18), v(18), inverse_mass(6);
  const Vector3d p = w[0] * a + w[1] * b + w[2] * c + Vector3d(0, 0, d0);
  x0 << a, b, c, p, p + Vector3d(0.2, 0, 0.1), p + Vector3d(0, 0.2, 0.1);  // a second, tilted triangle above
  inverse_mass << 1 / 0.5, 1 / 2.0, 1 / 1.0, 1 / 0.7, 1 / 0.7, 1 / 0.7;
  v << 0.1, 0, 0.2, -0.3, 0.1, 0.1, 0, 0.2, 0.3, 0.8, -0.4, -0.6, 0.8, -0.4, -0.6, 0.8, -0.4, -0.6;
  const auto relative = [&](const Eigen::VectorXd& vel) {
    return Vector3d(vel.segment<3>(9) - w[0] * vel.segment<3>(0) - w[1] * vel.segment<3>(3) -
                    w[2] * vel.segment<3>(6));
  };
  const auto momentum = [&](const Eigen::VectorXd& vel) {
    Vector3d sum = Vector3d::Zero();
    for (int i = 0; i < 6; ++i) sum += vel.segment<3>(3 * i) / inverse_mass[i];
    return sum;
  };
  const Vector3d before = relative(v), n = Vector3d::UnitZ();
  const Vector3d p_before = momentum(v);
  // One sweep and no other pair can act: the vertex's own triangle is incident to it.
  SelfCollision(triangles, 0.01, mu, 1).filter(x0, v, 0.01, inverse_mass);
  const Vector3d after = relative(v);
  const double normal_change = after.dot(n) - before.dot(n);
  EXPECT_NEAR(after.dot(n), (0.01 - d0) / 0.01, 1e-12)
      << "the pair separates at the rate that restores the thickness";
  const Vector3d slide_before = before - before.dot(n) * n, slide_after = after - after.dot(n) * n;
  EXPECT_NEAR(slide_after.norm(), slide_before.norm() - mu * normal_change, 1e-12);
  EXPECT_NEAR(slide_after.normalized().dot(slide_before.normalized()), 1, 1e-12)
      << "the slide keeps its direction";
  EXPECT_LT((momentum(v) - p_before).norm(), 1e-12);
}

// cloth_door at 10 x 14 cells through a long schedule of every palette entry.
TEST(SelfCollision, ClothDoorLongRunHasNoIntersectingTrianglePairs) {
  std::ifstream in(kScenes / "tiny/cloth_door.toml");
  std::stringstream text;
  text << in.rdbuf();
  const auto path = testing::scratch_dir("cloth_door_long") / "cloth_door.toml";
  std::ofstream(path) << std::regex_replace(text.str(), std::regex("cells = \\[5, 7\\]"), "cells = [10, 14]");
  const Scene scene = load_scene_file(path);
  ASSERT_EQ(scene.model.vertices(), 11 * 15);
  const OrbitStore orbit = simulate_schedule(
      scene, parse_schedule("open 1.2; stop 1; close 1.2; open 0.6; close 0.6; open 0.4; stop 1", scene));
  ASSERT_EQ(orbit.frames(), 300);
  int total = 0;
  for (int f = 0; f < orbit.frames(); ++f) {
    const Eigen::VectorXd x = orbit.positions.row(f).cast<double>().transpose();
    const int n = count_intersecting_pairs(x, scene.model.surface);
    EXPECT_EQ(n, 0) << "frame " << f;
    total += n;
  }
  EXPECT_EQ(total, 0);
}

}  // namespace
}  // namespace phasecast::precompute
