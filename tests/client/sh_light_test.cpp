// SH lights: probe conventions, rotation equals projecting the rotated
// function, and the support-frame light.

#include "phasecast/client/sh_light.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <cmath>
#include <numbers>

namespace phasecast::client {
namespace {

// A band-limited test function: a smooth lobe plus a band-3 term.
std::array<double, 3> lobe(const Eigen::Vector3d& w) {
  const double a = std::max(0.0, w.dot(Eigen::Vector3d(0.2, 0.9, 0.4).normalized()));
  const double v = 0.3 + 0.8 * w.x() * w.y() + 0.5 * w.z() * (5 * w.z() * w.z() - 3) + 0.2 * w.y();
  return {v, 2 * v + 0.1, a};
}

Eigen::Matrix3d some_rotation() {
  return (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(-1.1, Eigen::Vector3d(1, 0.3, 0.2).normalized()))
      .toRotationMatrix();
}

TEST(ShRotation, RotatingCoefficientsEqualsProjectingTheRotatedFunction) {
  const Eigen::Matrix3d R = some_rotation();
  const ShLight original = project_light(lobe, 96);
  // f_rot(w) = f(R^T w), projected directly.
  const ShLight projected =
      project_light([&](const Eigen::Vector3d& w) { return lobe(R.transpose() * w); }, 96);
  const Eigen::Matrix<double, 16, 16> D = sh_rotation(R);
  for (std::size_t c = 0; c < 3; ++c) {
    Eigen::Matrix<double, 16, 1> v;
    for (int k = 0; k < 16; ++k) v[k] = original.coefficients[c][static_cast<std::size_t>(k)];
    const Eigen::Matrix<double, 16, 1> rotated = D * v;
    for (int k = 0; k < 16; ++k) {
      // Quadrature error of the 96x192 product rule is ~1e-4 here; the
      // clamped lobe of channel 2 is not band-limited, so its projections
      // differ by the aliasing of bands > 3 only through the quadrature.
      EXPECT_NEAR(rotated[k], projected.coefficients[c][static_cast<std::size_t>(k)], 2e-3)
          << "channel " << c << " k " << k;
    }
  }
}

TEST(ShRotation, IsOrthogonalBlockDiagonalAndComposes) {
  const Eigen::Matrix3d R = some_rotation();
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto D = sh_rotation(R);
  // core::sh_basis returns float32 values: agreement to float precision.
  EXPECT_LT((D * D.transpose() - Eigen::Matrix<double, 16, 16>::Identity()).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((sh_rotation(R * Q) - sh_rotation(R) * sh_rotation(Q)).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((sh_rotation(Eigen::Matrix3d::Identity()) - Eigen::Matrix<double, 16, 16>::Identity())
                .cwiseAbs()
                .maxCoeff(),
            1e-12);
}

TEST(ShLight, DirectionalLightRotatedIntoSupportFrameFollowsTheSupport) {
  // A light from +x seen from a support rotated by R comes from R^T x.
  const Eigen::Matrix3d R = some_rotation();
  const ShLight world = directional_light(Eigen::Vector3d::UnitX(), {1, 1, 1});
  const ShLight local = light_in_support_frame(world, R);
  const ShLight expected = directional_light(R.transpose() * Eigen::Vector3d::UnitX(), {1, 1, 1});
  for (std::size_t k = 0; k < 16; ++k)
    EXPECT_NEAR(local.coefficients[0][k], expected.coefficients[0][k], 1e-5);
}

TEST(ShLight, GraceCathedralUsesCondonShortleySigns) {
  const ShLight g = light_probe("grace");
  // R-H L1m1 = (.39499, ...) is stored negated at k = 1; L10 unchanged at k = 2.
  EXPECT_FLOAT_EQ(g.coefficients[0][0], 0.78908f);
  EXPECT_FLOAT_EQ(g.coefficients[0][1], -0.39499f);
  EXPECT_FLOAT_EQ(g.coefficients[0][2], -0.33974f);
  EXPECT_FLOAT_EQ(g.coefficients[2][7], -0.13915f);
  for (std::size_t k = 9; k < 16; ++k) EXPECT_EQ(g.coefficients[1][k], 0.0f);
}

TEST(ShLight, WhiteFurnaceHasConstantRadianceOne) {
  const ShLight w = light_probe("white");
  EXPECT_NEAR(w.coefficients[1][0], 3.544908, 1e-5);
  const ShLight projected = project_light([](const Eigen::Vector3d&) {
    return std::array<double, 3>{1, 1, 1};
  });
  EXPECT_NEAR(projected.coefficients[2][0], 3.544908, 1e-4);
  // Midpoint rule with 128 polar samples: zonal terms carry ~2e-4 of quadrature error.
  for (std::size_t k = 1; k < 16; ++k) EXPECT_NEAR(projected.coefficients[2][k], 0, 5e-4);
}

TEST(ShLight, EveryNamedProbeIsFinite) {
  for (const auto& name : light_probe_names()) {
    const auto packed = light_probe(name).packed();
    for (float v : packed) EXPECT_TRUE(std::isfinite(v)) << name;
  }
}

TEST(ShLight, UnknownProbeNameIsRejectedWithTheKnownNames) {
  try {
    light_probe("cathedral");
    FAIL() << "expected an exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "light probe 'cathedral' is unknown (expected one of grace, sky, sun, white)");
  }
}

}  // namespace
}  // namespace phasecast::client
