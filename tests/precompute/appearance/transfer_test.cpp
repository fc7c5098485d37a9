// Diffuse PRT against closed forms (docs/transfer.md, shared/reference/spherical-harmonics.md).

#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/core/sh.h"
#include "phasecast/precompute/appearance/transfer_rays.h"
#include "test_meshes.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace phasecast {
namespace {

using precompute::compute_transfer;
using precompute::TransferMesh;
using precompute::TransferMode;
using precompute::TransferOptions;
using ::testing::HasSubstr;
constexpr double kPi = std::numbers::pi;

MatrixXfR transfer_of(const TransferMesh& m, TransferMode mode, int rays, int bounces = 0,
                      std::array<float, 3> albedo = {0.8f, 0.5f, 0.2f}) {
  TransferOptions o;
  o.mode = mode;
  o.rays = rays;
  o.bounces = bounces;
  o.albedo = albedo;
  return compute_transfer(m.positions, m.triangles, m.normals, o);
}

// Point of `m` at (x, y, z) within 1e-6, or -1.
Eigen::Index point_at(const TransferMesh& m, float x, float y, float z) {
  for (Eigen::Index i = 0; i < m.positions.rows(); ++i) {
    if ((m.positions.row(i) - Eigen::RowVector3f(x, y, z)).norm() < 1e-6f) return i;
  }
  return -1;
}

// Cosine-weighted fraction of the hemisphere of a point below one corner of
// an a x b rectangle parallel to it at height h (view factor, e.g. Howell's
// catalogue C-11): F = 1/(2 pi) [A/sqrt(1+A^2) atan(B/sqrt(1+A^2)) + (A<->B)].
double corner_view_factor(double a, double b, double h) {
  const double A = a / h, B = b / h;
  const double sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
  return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2 * kPi);
}

TEST(Transfer, SphereUnshadowedMatchesClosedForm) {
  const TransferMesh sphere = testing::icosphere(2);
  const std::array<float, 3> albedo{0.8f, 0.5f, 0.2f};
  const MatrixXfR T = transfer_of(sphere, TransferMode::unshadowed, 4096, 0, albedo);
  ASSERT_EQ(T.rows(), sphere.positions.rows());
  ASSERT_EQ(T.cols(), 48);
  double worst = 0;
  for (Eigen::Index p = 0; p < T.rows(); ++p) {
    const auto y = core::sh_basis(sphere.normals(p, 0), sphere.normals(p, 1), sphere.normals(p, 2));
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 16; ++k) {
        // T_k(n) = (rho/pi) A-hat_l Y_k(n)
        const double expected = albedo[static_cast<size_t>(c)] / kPi *
                                core::clamped_cosine_band(core::sh_band(k)) * y[static_cast<size_t>(k)];
        worst = std::max(worst, std::abs(T(p, 16 * c + k) - expected));
      }
    }
  }
  // Quadrature error of 4096 lattice directions on the kinked clamped cosine
  // (measured 2e-5 against coefficients up to 0.25).
  EXPECT_LT(worst, 2e-4);
}

TEST(Transfer, WhiteFurnaceUnshadowedGivesAlbedo) {
  const TransferMesh sphere = testing::icosphere(1);
  const MatrixXfR T = transfer_of(sphere, TransferMode::unshadowed, 4096, 0, {0.8f, 0.5f, 0.2f});
  const Eigen::MatrixXd e = testing::furnace(T);
  for (Eigen::Index p = 0; p < e.rows(); ++p) {
    EXPECT_NEAR(e(p, 0), 0.8, 2e-4);
    EXPECT_NEAR(e(p, 1), 0.5, 2e-4);
    EXPECT_NEAR(e(p, 2), 0.2, 2e-4);
  }
}

TEST(Transfer, ConvexCubeShadowedEqualsUnshadowedAndBouncesAddNothing) {
  const TransferMesh cube = testing::flat_cube();
  const MatrixXfR unshadowed = transfer_of(cube, TransferMode::unshadowed, 1024);
  const MatrixXfR shadowed = transfer_of(cube, TransferMode::shadowed, 1024);
  const MatrixXfR interreflected = transfer_of(cube, TransferMode::interreflected, 1024, 3);
  EXPECT_EQ(shadowed, unshadowed);
  EXPECT_EQ(interreflected, shadowed);
  EXPECT_GT(unshadowed.cwiseAbs().maxCoeff(), 0.1f);
}

TEST(Transfer, TessellatedSphereShadowedEqualsUnshadowed) {
  // Convex: every facet lies below the tangent plane of each vertex, so no ray
  // of the upper hemisphere can hit the mesh, however coarse the facets.
  const TransferMesh sphere = testing::icosphere(2);
  const MatrixXfR unshadowed = transfer_of(sphere, TransferMode::unshadowed, 1024);
  EXPECT_EQ(transfer_of(sphere, TransferMode::shadowed, 1024), unshadowed);
  EXPECT_EQ(transfer_of(sphere, TransferMode::interreflected, 1024, 2), unshadowed);
}

TEST(Transfer, PointUnderOccluderSeesExpectedFraction) {
  // Floor [-1, 1]^2 at z = 0; a 1 x 1 occluder centred 0.5 above it.
  const TransferMesh floor = testing::square(1.0f, 0.0f, 2, true);
  const double visible = 1 - 4 * corner_view_factor(0.5, 0.5, 0.5);
  for (const bool occluder_faces_up : {false, true}) {
    const TransferMesh scene = testing::merge(floor, testing::square(0.5f, 0.5f, 1, occluder_faces_up));
    const Eigen::Index centre = point_at(scene, 0, 0, 0);
    ASSERT_GE(centre, 0);
    const Eigen::MatrixXd e = testing::furnace(transfer_of(scene, TransferMode::shadowed, 16384));
    EXPECT_NEAR(e(centre, 0), 0.8 * visible, 1.5e-3) << "occluder faces up: " << occluder_faces_up;
    EXPECT_NEAR(e(centre, 2), 0.2 * visible, 0.4e-3);
  }
}

TEST(Transfer, ConcaveBoxGetsMoreLightWithEachBounce) {
  const TransferMesh box = testing::open_box(2);
  const Eigen::Index floor_point = point_at(box, 0, 0, -0.5f);
  ASSERT_GE(floor_point, 0);
  std::vector<double> exit;
  for (int bounces = 0; bounces <= 3; ++bounces) {
    exit.push_back(
        testing::furnace(transfer_of(box, TransferMode::interreflected, 2048, bounces))(floor_point, 0));
  }
  const double shadowed = testing::furnace(transfer_of(box, TransferMode::shadowed, 2048))(floor_point, 0);
  EXPECT_DOUBLE_EQ(exit[0], shadowed);
  for (size_t b = 1; b < exit.size(); ++b) {
    EXPECT_GT(exit[b], exit[b - 1]) << "bounce " << b;
    EXPECT_LT(exit[b], 0.8);  // never more than the albedo under a unit sky
  }
  // Each bounce carries at most rho times the previous one's light.
  EXPECT_LT(exit[2] - exit[1], 0.8 * (exit[1] - exit[0]) + 1e-9);
}

// Colour bleeding: a white floor beside one red wall reflects red light once
// light bounces, and only then (the shadowed floor stays white).
TEST(Transfer, RedWallBleedsOntoWhiteFloorOnlyThroughBounces) {
  const TransferMesh box = testing::open_box(4);
  const Eigen::Index floor_point = point_at(box, 0, 0, -0.5f);
  ASSERT_GE(floor_point, 0);
  TransferOptions o;
  o.rays = 2048;
  o.point_albedo = MatrixXfR::Constant(box.positions.rows(), 3, 0.8f);
  for (Eigen::Index p = 0; p < box.positions.rows(); ++p)
    if (box.normals(p, 0) < -0.9f) o.point_albedo.row(p) << 0.9f, 0.1f, 0.1f;  // the +x wall, facing in
  o.mode = TransferMode::shadowed;
  const Eigen::MatrixXd direct =
      testing::furnace(compute_transfer(box.positions, box.triangles, box.normals, o));
  EXPECT_DOUBLE_EQ(direct(floor_point, 0), direct(floor_point, 1));
  o.mode = TransferMode::interreflected;
  o.bounces = 2;
  const Eigen::MatrixXd lit =
      testing::furnace(compute_transfer(box.positions, box.triangles, box.normals, o));
  // Bounced light: 0.8 x (what the walls send); the red wall sends 9x more red than green.
  const double red = lit(floor_point, 0) - direct(floor_point, 0),
               green = lit(floor_point, 1) - direct(floor_point, 1);
  EXPECT_GT(green, 0);
  EXPECT_GT(red, 1.2 * green);
  // The uniform-albedo run with the same grey everywhere gives equal channels.
  o.point_albedo = MatrixXfR();
  o.albedo = {0.8f, 0.8f, 0.8f};
  const Eigen::MatrixXd grey =
      testing::furnace(compute_transfer(box.positions, box.triangles, box.normals, o));
  EXPECT_NEAR(grey(floor_point, 0), grey(floor_point, 1), 1e-12);
}

TEST(Transfer, DoubleSidedBackFacesGetTheirOwnTransfer) {
  const TransferMesh sheet = precompute::make_double_sided(testing::square(1.0f, 0.0f, 2, true));
  const TransferMesh scene = testing::merge(sheet, testing::square(0.5f, 0.5f, 1, false));
  const Eigen::Index front = point_at(scene, 0, 0, 0);
  ASSERT_EQ(front, 4);
  const Eigen::Index back = front + 9;  // the copy made by make_double_sided
  const MatrixXfR T = transfer_of(scene, TransferMode::shadowed, 4096);
  const Eigen::MatrixXd e = testing::furnace(T);
  EXPECT_NEAR(e(back, 0), 0.8, 2e-3);  // nothing below the sheet
  EXPECT_LT(e(front, 0), 0.5);         // occluded from above
  EXPECT_LT(T(back, 2), 0);            // the z-band-1 coefficient points down
  EXPECT_GT(T(front, 2), 0);
}

TEST(Transfer, BounceGathersFromTheSideTheRaySees) {
  // Light bounced off a double-sided occluder's underside must equal that of
  // a one-sided occluder facing down; a one-sided occluder facing up shows
  // the floor only its back, which reflects nothing.
  const TransferMesh floor = testing::square(1.0f, 0.0f, 2, true);
  const TransferMesh down = testing::square(0.5f, 0.5f, 2, false);
  const TransferMesh up = testing::square(0.5f, 0.5f, 2, true);
  const Eigen::Index centre = 4;
  auto floor_exit = [&](const TransferMesh& occluder, TransferMode mode) {
    const TransferMesh scene = testing::merge(floor, occluder);
    return testing::furnace(transfer_of(scene, mode, 4096, 1))(centre, 0);
  };
  const double shadowed = floor_exit(down, TransferMode::shadowed);
  const double one_sided_down = floor_exit(down, TransferMode::interreflected);
  const double two_sided = floor_exit(precompute::make_double_sided(up), TransferMode::interreflected);
  const double one_sided_up = floor_exit(up, TransferMode::interreflected);
  EXPECT_GT(one_sided_down, shadowed + 0.01);
  EXPECT_NEAR(two_sided, one_sided_down, 1e-6);
  EXPECT_DOUBLE_EQ(one_sided_up, shadowed);
}

TEST(Transfer, DeterministicAcrossThreadCounts) {
  const TransferMesh box = testing::open_box(2);
  TransferOptions o;
  o.mode = TransferMode::interreflected;
  o.rays = 512;
  o.bounces = 2;
  o.threads = 1;
  const MatrixXfR one = compute_transfer(box.positions, box.triangles, box.normals, o);
  o.threads = 3;
  const MatrixXfR three = compute_transfer(box.positions, box.triangles, box.normals, o);
  EXPECT_EQ(one, three);
  EXPECT_EQ(one, compute_transfer(box.positions, box.triangles, box.normals, o));
}

TEST(Transfer, ProgressReachesTotal) {
  const TransferMesh box = testing::open_box(2);
  TransferOptions o;
  o.mode = TransferMode::interreflected;
  o.rays = 64;
  o.bounces = 1;
  std::vector<std::string> finished;
  o.progress = [&](const char* stage, long done, long total) {
    EXPECT_LE(done, total);
    if (done == total) finished.emplace_back(stage);
  };
  compute_transfer(box.positions, box.triangles, box.normals, o);
  EXPECT_THAT(finished, ::testing::Contains("direct"));
  EXPECT_THAT(finished, ::testing::Contains("bounce 1/1"));
}

TEST(Transfer, SphereDirectionsAreUnitAndBalanced) {
  const MatrixXfR d = precompute::sphere_directions(1000);
  ASSERT_EQ(d.rows(), 1000);
  EXPECT_LT((d.rowwise().norm().array() - 1).abs().maxCoeff(), 1e-6f);
  EXPECT_LT(d.colwise().mean().norm(), 1e-3f);  // no preferred direction
  try {
    precompute::sphere_directions(0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "sphere_directions: count must be >= 1, got 0");
  }
}

TEST(Transfer, RayCasterResolvesDoubleSidedPairs) {
  const TransferMesh sheet = precompute::make_double_sided(testing::square(1.0f, 0.0f, 1, true));
  const precompute::RayCaster caster(sheet.positions, sheet.triangles);
  EXPECT_EQ(caster.built_triangles(), 2);  // four triangles, two merged pairs
  const auto from_above = caster.closest({0.2f, 0.1f, 1.0f}, {0, 0, -1});
  ASSERT_TRUE(from_above.hit && from_above.front);
  for (const auto p : from_above.points) EXPECT_LT(p, 4u);  // the upward-facing copy
  EXPECT_NEAR(from_above.t, 1.0f, 1e-6f);
  const auto from_below = caster.closest({0.2f, 0.1f, -1.0f}, {0, 0, 1});
  ASSERT_TRUE(from_below.hit && from_below.front);
  for (const auto p : from_below.points) EXPECT_GE(p, 4u);  // the downward-facing copy
  float sum = 0;
  Eigen::RowVector3f at = Eigen::RowVector3f::Zero();
  for (int j = 0; j < 3; ++j) {
    sum += from_below.weights[static_cast<size_t>(j)];
    at += from_below.weights[static_cast<size_t>(j)] *
          sheet.positions.row(from_below.points[static_cast<size_t>(j)]);
  }
  EXPECT_NEAR(sum, 1.0f, 1e-6f);
  EXPECT_LT((at - Eigen::RowVector3f(0.2f, 0.1f, 0)).norm(), 1e-5f);  // barycentrics follow the twin's order
  EXPECT_TRUE(caster.occluded({0, 0, 1}, {0, 0, -1}));
  EXPECT_FALSE(caster.occluded({0, 0, 1}, {0, 0, 1}));
  EXPECT_FALSE(caster.occluded({0, 0, 1}, {0, 0, -1}, 0.5f));
}

// ---- rejected inputs: one line naming the input and what was expected -------

std::string failure_of(const TransferMesh& m, const TransferOptions& o) {
  try {
    compute_transfer(m.positions, m.triangles, m.normals, o);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}

TEST(TransferRejects, BadOptions) {
  const TransferMesh cube = testing::flat_cube();
  TransferOptions o;
  o.rays = 0;
  EXPECT_EQ(failure_of(cube, o), "transfer: rays must be in 1..1048576, got 0");
  o.rays = (1 << 20) + 1;
  EXPECT_EQ(failure_of(cube, o), "transfer: rays must be in 1..1048576, got 1048577");
  o = {};
  o.bounces = -1;
  EXPECT_EQ(failure_of(cube, o), "transfer: bounces must be >= 0, got -1");
  o = {};
  o.albedo = {0.5f, 1.5f, 0.5f};
  EXPECT_EQ(failure_of(cube, o), "transfer: albedo channel 1 must be in [0, 1], got 1.5");
  o.albedo = {0.5f, 0.5f, NAN};
  EXPECT_EQ(failure_of(cube, o), "transfer: albedo channel 2 must be in [0, 1], got nan");
  o = {};
  o.threads = -2;
  EXPECT_EQ(failure_of(cube, o), "transfer: threads must be >= 0, got -2");
  o = {};
  o.point_albedo = MatrixXfR::Constant(cube.positions.rows(), 3, 0.5f);
  o.point_albedo(3, 1) = 2.0f;
  EXPECT_EQ(failure_of(cube, o), "transfer: point_albedo of point 3 channel 1 must be in [0, 1], got 2");
  o.point_albedo = MatrixXfR::Constant(cube.positions.rows() + 1, 3, 0.5f);
  EXPECT_THAT(failure_of(cube, o), HasSubstr("point_albedo has"));
}

TEST(TransferRejects, BadMesh) {
  TransferMesh m = testing::flat_cube();
  m.normals(3, 0) = 2;
  EXPECT_THAT(failure_of(m, {}), HasSubstr("transfer: normal 3 must be a unit vector, has length"));
  m = testing::flat_cube();
  m.positions(5, 1) = NAN;
  EXPECT_EQ(failure_of(m, {}), "transfer: position 5 is not finite");
  m = testing::flat_cube();
  m.triangles(2, 1) = 99;
  EXPECT_EQ(failure_of(m, {}), "transfer: triangle 2 refers to point 99, expected < 24");
  m = testing::flat_cube();
  m.normals.conservativeResize(10, 3);
  EXPECT_EQ(failure_of(m, {}), "transfer: normals must be 24 x 3 (one per point), got 10 x 3");
  m.positions.resize(0, 3);
  EXPECT_EQ(failure_of(m, {}), "transfer: positions must be S x 3 with S >= 1, got 0 x 3");
}

TEST(TransferRejects, UnknownMode) {
  EXPECT_EQ(precompute::parse_transfer_mode("interreflected"), TransferMode::interreflected);
  try {
    precompute::parse_transfer_mode("glossy");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(),
                 "unknown transfer mode 'glossy' (expected unshadowed, shadowed or interreflected)");
  }
}

}  // namespace
}  // namespace phasecast
