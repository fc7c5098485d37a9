#pragma once
// Real spherical harmonics of order 4 (bands l = 0..3, 16 functions) in the
// convention of shared/reference/spherical-harmonics.md: index k = l(l+1)+m,
// Condon-Shortley phase included, direction (x, y, z) with z = cos(theta).
// Used by transfer precompute (§4.1, Sloan et al. 2002) and by the client's lights.

#include <array>

namespace phasecast::core {

inline constexpr int kShBands = 4;
inline constexpr int kShCoefficients = kShBands * kShBands;  // 16
inline constexpr int kShChannels = 3;                        // RGB transfer vectors
using ShVector = std::array<float, kShCoefficients>;

// Y_k(x, y, z) for k = 0..15; (x, y, z) must be a unit vector.
ShVector sh_basis(double x, double y, double z);

// Band index l of coefficient k.
constexpr int sh_band(int k) {
  return k < 1 ? 0 : k < 4 ? 1 : k < 9 ? 2 : 3;
}

// Convolution constants A-hat_l of the clamped cosine max(0, n.w) for l = 0..3:
// pi, 2pi/3, pi/4, 0 (Ramamoorthi & Hanrahan 2001).
double clamped_cosine_band(int l);

}  // namespace phasecast::core
