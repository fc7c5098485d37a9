// Spherical harmonics against shared/reference/spherical-harmonics.md and
// against their defining properties (orthonormality by quadrature).

#include "phasecast/core/sh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace phasecast {
namespace {

TEST(SphericalHarmonics, MatchesReferenceTableAtADirection) {
  const double x = 0.48, y = -0.6, z = std::sqrt(1 - x * x - y * y);
  const auto Y = core::sh_basis(x, y, z);
  const double expected[16] = {0.282095,
                               -0.488603 * y,
                               0.488603 * z,
                               -0.488603 * x,
                               1.092548 * x * y,
                               -1.092548 * y * z,
                               0.315392 * (3 * z * z - 1),
                               -1.092548 * x * z,
                               0.546274 * (x * x - y * y),
                               -0.590044 * y * (3 * x * x - y * y),
                               2.890611 * x * y * z,
                               -0.457046 * y * (5 * z * z - 1),
                               0.373176 * z * (5 * z * z - 3),
                               -0.457046 * x * (5 * z * z - 1),
                               1.445306 * z * (x * x - y * y),
                               -0.590044 * x * (x * x - 3 * y * y)};
  for (int k = 0; k < 16; ++k) EXPECT_NEAR(Y[static_cast<size_t>(k)], expected[k], 2e-6) << "k = " << k;
}

TEST(SphericalHarmonics, AreOrthonormalOnTheSphere) {
  // Midpoint quadrature in (cos theta, phi): exact enough for bands <= 3.
  constexpr int n = 200;
  double gram[16][16] = {};
  for (int i = 0; i < n; ++i) {
    const double z = -1 + (i + 0.5) * 2.0 / n;
    const double r = std::sqrt(1 - z * z);
    for (int j = 0; j < 2 * n; ++j) {
      const double phi = (j + 0.5) * std::numbers::pi / n;
      const auto Y = core::sh_basis(r * std::cos(phi), r * std::sin(phi), z);
      const double w = (2.0 / n) * (std::numbers::pi / n);
      for (int a = 0; a < 16; ++a)
        for (int b = 0; b < 16; ++b) gram[a][b] += w * Y[static_cast<size_t>(a)] * Y[static_cast<size_t>(b)];
    }
  }
  for (int a = 0; a < 16; ++a)
    for (int b = 0; b < 16; ++b) EXPECT_NEAR(gram[a][b], a == b ? 1.0 : 0.0, 2e-3) << a << "," << b;
}

TEST(SphericalHarmonics, ClampedCosineConstantsMatchProjection) {
  // Project max(0, z) onto the zonal harmonics and compare sqrt(4pi/(2l+1)) z_l = A-hat_l.
  constexpr int n = 20000;
  const int zonal[4] = {0, 2, 6, 12};
  for (int l = 0; l < 4; ++l) {
    double zl = 0;
    for (int i = 0; i < n; ++i) {
      const double z = (i + 0.5) / n;  // upper hemisphere only
      zl += 2 * std::numbers::pi * (1.0 / n) * z *
            core::sh_basis(0, std::sqrt(1 - z * z), z)[static_cast<size_t>(zonal[l])];
    }
    EXPECT_NEAR(std::sqrt(4 * std::numbers::pi / (2 * l + 1)) * zl, core::clamped_cosine_band(l), 1e-4)
        << "l = " << l;
  }
}

TEST(SphericalHarmonics, BandOfIndex) {
  EXPECT_EQ(core::sh_band(0), 0);
  EXPECT_EQ(core::sh_band(3), 1);
  EXPECT_EQ(core::sh_band(4), 2);
  EXPECT_EQ(core::sh_band(8), 2);
  EXPECT_EQ(core::sh_band(9), 3);
  EXPECT_EQ(core::sh_band(15), 3);
}

}  // namespace
}  // namespace phasecast
