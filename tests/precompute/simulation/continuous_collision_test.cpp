// Continuous collision and its fail-safe against closed forms (crossing times
// of linear motion), and the guarantee on a two-layer cloth pressed together
// by the air: no intersecting triangle pair in any frame while the layers stay
// closer than twice the thickness (so the guarantee is tested where it matters).

#include "phasecast/precompute/simulation/continuous_collision.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "run_tool.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>

namespace phasecast::precompute {
namespace {

using Eigen::Vector3d;
using Points = std::array<Vector3d, 4>;

// The unit triangle in z = 0, and a point falling through it at (0.2, 0.2).
TEST(ContinuousCollision, VertexTriangleContactAtTheCrossingTime) {
  const Points start = {Vector3d(0.2, 0.2, 0.3), Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)};
  Points end = start;
  end[0].z() = -0.1;  // crosses z = 0 at t = 0.3 / 0.4
  const auto t = vertex_triangle_contact(start, end, 1e-9);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 0.75, 1e-9);
  end[0] = Vector3d(0.8, 0.8, -0.1);  // crosses the plane outside the triangle (x + y > 1 there)
  EXPECT_FALSE(vertex_triangle_contact(start, end, 1e-9).has_value());
}

// The triangle moves up through a still point: only relative motion counts.
TEST(ContinuousCollision, MovingTriangleMeetsAStillPoint) {
  const Points start = {Vector3d(0.25, 0.25, 0), Vector3d(0, 0, -0.2), Vector3d(1, 0, -0.2),
                        Vector3d(0, 1, -0.2)};
  Points end = start;
  for (size_t k = 1; k < 4; ++k) end[k].z() = 0.2;
  const auto t = vertex_triangle_contact(start, end, 1e-9);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 0.5, 1e-9);
}

// Edge (x axis) and an edge along y, 0.1 above, falling by 0.4: they meet at t = 1/4.
TEST(ContinuousCollision, EdgeEdgeContactAndAMiss) {
  const Points start = {Vector3d(-1, 0, 0), Vector3d(1, 0, 0), Vector3d(0, -1, 0.1), Vector3d(0, 1, 0.1)};
  Points end = start;
  end[2].z() = end[3].z() = -0.3;
  const auto t = edge_edge_contact(start, end, 1e-9);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 0.25, 1e-9);
  Points beside_start = start, beside_end = end;
  for (size_t k = 2; k < 4; ++k) beside_start[k].x() += 2.0, beside_end[k].x() += 2.0;
  EXPECT_FALSE(
      edge_edge_contact(beside_start, beside_end, 1e-9).has_value());  // falls beyond the first edge's end
}

// Recorded from the paper-size towel (a front-layer vertex and a back-layer
// triangle, both clipped onto the door's padded face z = 4 mm): the pair ends
// exactly coplanar and touching, and rounding made the coplanarity cubic's
// value at the end the sign of its start, so no root was bracketed and the
// vertex was left lying in the triangle (an intersecting pair in every later frame).
TEST(ContinuousCollision, ContactExactlyAtTheEndOfTheStepIsFound) {
  const Points start = {Vector3d(0.38176286705466222, 1.5028187074046977, 0.0057328543666030967),
                        Vector3d(0.36722424169573625, 1.5060747391556053, 0.004),
                        Vector3d(0.38238914770454135, 1.5061742711912678, 0.004),
                        Vector3d(0.3824090851912566, 1.4920154329783042, 0.004)};
  const Points end = {Vector3d(0.38175086263551611, 1.5023849421579816, 0.004),
                      Vector3d(0.36754671792592208, 1.5072372393753366, 0.004),
                      Vector3d(0.3824643487747042, 1.5071462009234999, 0.004),
                      Vector3d(0.38214841787422038, 1.4931459767764561, 0.004)};
  const auto t = vertex_triangle_contact(start, end, 1e-6);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 1.0, 1e-9);
}

// Two triangles, the second thrown through the first within one step.
struct Throw {
  Eigen::MatrixXi triangles{{0, 1, 2}, {3, 4, 5}};
  Eigen::VectorXd x0{18}, v{18}, inverse_mass = Eigen::VectorXd::Ones(6);
};
Throw throw_through() {
  Throw t;
  t.x0 << 0, 0, 0, 1, 0, 0, 0, 1, 0,                   // lower, z = 0
      0.1, 0.1, 0.05, 0.9, 0.1, 0.05, 0.1, 0.9, 0.05;  // upper, 5 cm above, overlapping in x, y
  t.v.setZero();
  for (int k = 3; k < 6; ++k) t.v[3 * k + 2] = -10;  // 10 m/s down: 10 cm in a 10 ms step
  return t;
}

bool crosses(const ContinuousCollision& ccd, const Throw& t, double h) {
  return !ccd.detect(t.x0, t.x0 + h * t.v).empty();
}

TEST(ContinuousCollision, ImpulsesStopTheCrossing) {
  Throw t = throw_through();
  const ContinuousCollision ccd(t.triangles, 1e-4);
  ASSERT_TRUE(crosses(ccd, t, 0.01));
  const Vector3d momentum_before = t.v.reshaped(3, 6).rowwise().sum();
  const CcdReport r = ccd.resolve(t.x0, t.v, 0.01, t.inverse_mass, [](int, const Vector3d&) { return true; });
  EXPECT_GT(r.collisions, 0);
  EXPECT_FALSE(crosses(ccd, t, 0.01));
  EXPECT_TRUE((Vector3d(t.v.reshaped(3, 6).rowwise().sum()) - momentum_before).norm() <
              1e-9);  // inelastic, equal masses
}

// With no impulse passes only the fail-safe acts: one zone, moving with the mean velocity.
TEST(ContinuousCollision, FailSafeZoneMovesRigidlyWithTheMeanVelocity) {
  Throw t = throw_through();
  const ContinuousCollision ccd(t.triangles, 1e-4, /*passes=*/0);
  const CcdReport r = ccd.resolve(t.x0, t.v, 0.01, t.inverse_mass, [](int, const Vector3d&) { return true; });
  EXPECT_FALSE(crosses(ccd, t, 0.01));
  EXPECT_EQ(r.zone_vertices, 6);
  EXPECT_EQ(r.frozen_vertices, 0);
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(t.v[3 * k + 2], -5.0, 1e-12) << "vertex " << k;
}

TEST(ContinuousCollision, FailSafeHoldsAZoneWithAPinnedVertex) {
  Throw t = throw_through();
  t.inverse_mass[0] = 0;  // the lower triangle's corner is attached
  const ContinuousCollision ccd(t.triangles, 1e-4, /*passes=*/0);
  const CcdReport r = ccd.resolve(t.x0, t.v, 0.01, t.inverse_mass, [](int, const Vector3d&) { return true; });
  EXPECT_FALSE(crosses(ccd, t, 0.01));
  EXPECT_EQ(r.frozen_vertices, 6);
  EXPECT_TRUE(t.v.isZero(0));
}

TEST(ContinuousCollision, FailSafeHoldsAVertexThatWouldEndInadmissibly) {
  Throw t = throw_through();
  t.v.setZero();
  t.v[2] = 1.0;  // vertex 0 rises into a half-space z > 0.005 forbidden to it
  const ContinuousCollision ccd(t.triangles, 1e-4);
  const CcdReport r = ccd.resolve(t.x0, t.v, 0.01, t.inverse_mass,
                                  [](int i, const Vector3d& end) { return i != 0 || end.z() < 0.005; });
  EXPECT_EQ(r.frozen_vertices, 1);
  EXPECT_TRUE(t.v.isZero(0));
}

// A towel's two layers, 6 mm apart (thickness 4 mm), pinned along the top and
// pressed together by the air of an opening door, then let swing.
Scene two_layer_towel() {
  const std::string layer = R"(
[[body]]
name = "{name}"
energies = ["membrane", "bending"]
density = 0.2
young = 400
bending = 4e-6
drag = 1.5
grid = { origin = [0.2, 0.6, {z}], u = [0.3, 0, 0], v = [0, -0.4, 0], cells = [8, 10] }
pin = { min = [0.1, 0.59, 0], max = [0.6, 0.61, 0.1] }
)";
  const auto make_layer = [&layer](const char* name, const char* z) {
    std::string s = layer;
    s.replace(s.find("{name}"), 6, name);
    s.replace(s.find("{z}"), 3, z);
    return s;
  };
  const std::string text = R"(name = "two_layer_towel"
[simulation]
frame_dt = 0.02
substeps = 2
newton_iterations = 2
mass_damping = 0.05
stiffness_damping = 0.003
friction = 0.4
[support]
motion = "rotational"
axis = [0, -1, 0]
[contact]
thickness = 0.004
self_collision = true
[[obstacle]]
name = "door"
min = [0.02, 0.0, -0.04]
max = [0.82, 0.8, 0.0]
[[palette]]
name = "open"
alpha_impulse = [0, -1.5, 0]
alpha_forcing = [0, -1.5, 0]
[[palette]]
name = "stop"
alpha_impulse = [0, 0, 0]
alpha_forcing = [0, 0, 0]
[[palette]]
name = "close"
alpha_impulse = [0, 1.5, 0]
alpha_forcing = [0, 1.5, 0]
)" + make_layer("back", "0.024") +
                           make_layer("front", "0.030");
  // One folder per test: ctest runs the tests that build this towel side by side.
  const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
  const auto path = testing::scratch_dir("two_layer_towel_" + test) / "towel.toml";
  std::ofstream(path) << text;
  return load_scene_file(path);
}

TEST(ContinuousCollision, PressedLayersNeverIntersectWhileInContact) {
  const Scene scene = two_layer_towel();
  const OrbitStore orbit =
      simulate_schedule(scene, parse_schedule("open 0.6; stop 0.6; close 0.6; stop 0.6", scene));
  const ContactSummary c = summarize_contact(orbit.positions, scene.model.surface, 2 * scene.model.thickness,
                                             scene.model.thickness);
  EXPECT_EQ(c.frames_intersecting, 0) << "worst frame: " << c.worst_intersecting << " pairs";
  EXPECT_GE(c.frames_close, 0.3 * c.frames) << "the layers must stay in contact range for the check to bite";
  EXPECT_GE(c.frames_in_contact, 0.3 * c.frames)
      << "the layers must press on each other for the check to bite";
}

}  // namespace
}  // namespace phasecast::precompute

namespace phasecast::precompute {
namespace {

// Steps of the pressed towel with a random jitter of up to 6 mm (the layers'
// gap) on top of the simulator's own motion, so that the layers cross and
// need several impulse passes and impact zones.
struct ContactSteps {
  Scene scene = two_layer_towel();
  OrbitStore orbit = simulate_schedule(scene, parse_schedule("open 0.6; stop 0.3", scene));
  Eigen::VectorXd inverse_mass = Eigen::VectorXd::Zero(scene.model.vertices());
  double h = scene.simulation.frame_dt;

  ContactSteps() {
    for (int i = 0; i < scene.model.vertices(); ++i)
      inverse_mass[i] = scene.model.pinned[static_cast<size_t>(i)] ? 0 : 1 / scene.model.mass[i];
  }
  Eigen::VectorXd x(int frame) const { return orbit.positions.row(frame).transpose().cast<double>(); }
  Eigen::VectorXd v(int frame) const {
    std::mt19937 rng(static_cast<unsigned>(frame));
    std::uniform_real_distribution<double> jitter(-0.3, 0.3);  // m/s: 6 mm over h = 20 ms
    Eigen::VectorXd v = (x(frame + 1) - x(frame)) / h;
    for (Eigen::Index i = 0; i < v.size(); ++i)
      if (inverse_mass[i / 3] > 0) v[i] += jitter(rng);
    return v;
  }
};

// The incremental detection (only pairs of moved vertices tested again) gives
// the whole detection's velocities bit for bit, on steps where the layers collide.
TEST(ContinuousCollision, IncrementalDetectionGivesTheWholeDetectionsVelocities) {
  const ContactSteps steps;
  const ContinuousCollision whole(steps.scene.model.surface, 1e-4, 6, /*incremental=*/false);
  const ContinuousCollision incremental(steps.scene.model.surface, 1e-4, 6, /*incremental=*/true);
  const auto anywhere = [](int, const Vector3d&) { return true; };
  int colliding_steps = 0;
  for (int f = 0; f + 1 < steps.orbit.frames(); f += 2) {
    Eigen::VectorXd a = steps.v(f), b = a;
    const CcdReport ra = whole.resolve(steps.x(f), a, steps.h, steps.inverse_mass, anywhere);
    const CcdReport rb = incremental.resolve(steps.x(f), b, steps.h, steps.inverse_mass, anywhere);
    ASSERT_TRUE(a == b) << "frame " << f << ": velocities differ by " << (a - b).lpNorm<Eigen::Infinity>();
    EXPECT_EQ(ra.collisions, rb.collisions) << "frame " << f;
    EXPECT_EQ(ra.zone_vertices, rb.zone_vertices) << "frame " << f;
    colliding_steps += ra.collisions > 0;
  }
  EXPECT_GE(colliding_steps, 5) << "too few colliding steps for the comparison to bite";
}

// The simulator with [contact] incremental_ccd = false (every detection whole)
// records the same orbit, bit for bit, as with the default incremental one.
TEST(ContinuousCollision, WholeDetectionScenesRecordTheSameOrbit) {
  const ContactSteps steps;  // its orbit: the default, incremental detection
  Scene whole = steps.scene;
  whole.model.incremental_ccd = false;
  const OrbitStore orbit = simulate_schedule(whole, parse_schedule("open 0.6; stop 0.3", whole));
  EXPECT_TRUE(orbit.positions == steps.orbit.positions);
  EXPECT_TRUE(orbit.velocities == steps.orbit.velocities);
}

// detect_moved after moving some vertices lists exactly what detect lists, in its order.
TEST(ContinuousCollision, DetectMovedListsWhatDetectListsInItsOrder) {
  const ContactSteps steps;
  const ContinuousCollision ccd(steps.scene.model.surface, 1e-4);
  const int f = 10;
  const Eigen::VectorXd x0 = steps.x(f), x1 = x0 + steps.h * steps.v(f);
  const auto before = ccd.detect(x0, x1);
  ASSERT_FALSE(before.empty());
  // Undo the motion of every third vertex: their pairs change, the rest do not.
  Eigen::VectorXd x1b = x1;
  std::vector<std::uint8_t> moved(static_cast<size_t>(steps.scene.model.vertices()), 0);
  for (int i = 0; i < steps.scene.model.vertices(); i += 3)
    x1b.segment<3>(3 * i) = x0.segment<3>(3 * i), moved[i] = 1;
  const auto truth = ccd.detect(x0, x1b);
  const auto again = ccd.detect_moved(x0, x1b, before, moved);
  ASSERT_EQ(again.size(), truth.size());
  EXPECT_NE(truth.size(), before.size()) << "the moved vertices changed nothing: the check does not bite";
  for (size_t k = 0; k < truth.size(); ++k) {
    EXPECT_EQ(again[k].vertex, truth[k].vertex) << k;
    EXPECT_EQ(again[k].weight, truth[k].weight) << k;
    EXPECT_TRUE(again[k].normal == truth[k].normal) << k;
  }
}

}  // namespace
}  // namespace phasecast::precompute
