#include "phasecast/core/sh.h"

#include <numbers>

namespace phasecast::core {

ShVector sh_basis(double x, double y, double z) {
  // Constants: shared/reference/spherical-harmonics.md (checked in tests/core/sh_test.cpp).
  constexpr double c0 = 0.2820947917738781;
  constexpr double c1 = 0.4886025119029199;
  constexpr double c2a = 1.092548430592079;
  constexpr double c2b = 0.9461746957575601, c2c = 0.3153915652525201;
  constexpr double c2d = 0.5462742152960395;
  constexpr double c3a = 0.5900435899266435;
  constexpr double c3b = 2.890611442640554;
  constexpr double c3c = 0.4570457994644658;
  constexpr double c3d = 1.865881662950577, c3e = 1.119528997770346;
  constexpr double c3f = 1.445305721320277;
  const double x2 = x * x, y2 = y * y, z2 = z * z;
  return {static_cast<float>(c0),
          static_cast<float>(-c1 * y),
          static_cast<float>(c1 * z),
          static_cast<float>(-c1 * x),
          static_cast<float>(c2a * x * y),
          static_cast<float>(-c2a * y * z),
          static_cast<float>(c2b * z2 - c2c),
          static_cast<float>(-c2a * x * z),
          static_cast<float>(c2d * (x2 - y2)),
          static_cast<float>(-c3a * y * (3 * x2 - y2)),
          static_cast<float>(c3b * x * y * z),
          static_cast<float>(-c3c * y * (5 * z2 - 1)),
          static_cast<float>(c3d * z2 * z - c3e * z),
          static_cast<float>(-c3c * x * (5 * z2 - 1)),
          static_cast<float>(c3f * z * (x2 - y2)),
          static_cast<float>(-c3a * x * (x2 - 3 * y2))};
}

double clamped_cosine_band(int l) {
  constexpr double pi = std::numbers::pi;
  switch (l) {
    case 0:
      return pi;
    case 1:
      return 2 * pi / 3;
    case 2:
      return pi / 4;
    default:
      return 0;  // band 3 of the clamped cosine vanishes
  }
}

}  // namespace phasecast::core
