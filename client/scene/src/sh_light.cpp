#include "phasecast/client/sh_light.h"

#include "phasecast/core/package.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <Eigen/Dense>

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace phasecast::client {
namespace {

constexpr double kPi = std::numbers::pi;

using ShMatrix = Eigen::Matrix<double, Eigen::Dynamic, 16>;

Eigen::Matrix<double, 1, 16> sh_row(const Eigen::Vector3d& d) {
  const auto y = core::sh_basis(d.x(), d.y(), d.z());
  Eigen::Matrix<double, 1, 16> row;
  for (int k = 0; k < 16; ++k) row[k] = y[static_cast<std::size_t>(k)];
  return row;
}

// Fixed, well-spread fitting directions (Fibonacci sphere).
const std::vector<Eigen::Vector3d>& fit_directions() {
  static const std::vector<Eigen::Vector3d> dirs = [] {
    std::vector<Eigen::Vector3d> d;
    const int n = 64;
    const double golden = kPi * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
      const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1.0 - z * z), phi = golden * i;
      d.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
    }
    return d;
  }();
  return dirs;
}

// Least-squares solver for coefficients from values at fit_directions().
const Eigen::Matrix<double, 16, Eigen::Dynamic>& fit_pseudo_inverse() {
  static const Eigen::Matrix<double, 16, Eigen::Dynamic> pinv = [] {
    const auto& dirs = fit_directions();
    ShMatrix A(static_cast<Eigen::Index>(dirs.size()), 16);
    for (std::size_t i = 0; i < dirs.size(); ++i) A.row(static_cast<Eigen::Index>(i)) = sh_row(dirs[i]);
    return Eigen::Matrix<double, 16, Eigen::Dynamic>(
        A.colPivHouseholderQr().solve(Eigen::MatrixXd::Identity(A.rows(), A.rows())));
  }();
  return pinv;
}

// Grace Cathedral, Ramamoorthi & Hanrahan 2001 (9 coefficients, RGB, their
// all-positive constants): odd |m| entries negated for the Condon-Shortley
// convention of core/sh.h (shared/reference/spherical-harmonics.md).
ShLight grace_cathedral() {
  const double rh[9][3] = {
      {.78908, .43710, .54161},    {.39499, .34989, .60488},    {-.33974, -.18236, -.26940},
      {-.29213, -.05562, .00944},  {-.11141, -.05090, -.12231}, {-.26240, -.22401, -.47479},
      {-.15570, -.09471, -.14733}, {.56014, .21444, .13915},    {.21205, -.05432, -.30374}};
  const int odd_m[9] = {0, 1, 0, 1, 0, 1, 0, 1, 0};
  ShLight light;
  for (int k = 0; k < 9; ++k) {
    for (int c = 0; c < 3; ++c) {
      light.coefficients[static_cast<std::size_t>(c)][static_cast<std::size_t>(k)] =
          static_cast<float>(odd_m[k] ? -rh[k][c] : rh[k][c]);
    }
  }
  return light;
}

ShLight sky() {
  return project_light([](const Eigen::Vector3d& w) -> std::array<double, 3> {
    if (w.y() < 0) return {0.18, 0.16, 0.14};  // ground
    const double t = w.y();
    return {0.45 + 0.35 * t, 0.60 + 0.30 * t, 0.95 + 0.05 * t};
  });
}

ShLight sun() {
  ShLight light = directional_light(Eigen::Vector3d(0.3, 0.8, 0.52).normalized(), {2.6, 2.45, 2.2});
  const ShLight ambient = sky();
  for (int c = 0; c < 3; ++c) {
    for (int k = 0; k < 16; ++k) {
      light.coefficients[static_cast<std::size_t>(c)][static_cast<std::size_t>(k)] +=
          0.3f * ambient.coefficients[static_cast<std::size_t>(c)][static_cast<std::size_t>(k)];
    }
  }
  return light;
}

ShLight white_furnace() {
  ShLight light;
  for (auto& channel : light.coefficients) channel[0] = static_cast<float>(4 * kPi * 0.2820947917738781);
  return light;
}

}  // namespace

std::array<float, 48> ShLight::packed() const {
  std::array<float, 48> out{};
  for (std::size_t c = 0; c < 3; ++c) {
    for (std::size_t k = 0; k < 16; ++k) out[16 * c + k] = coefficients[c][k];
  }
  return out;
}

std::vector<std::string> light_probe_names() {
  return {core::kLightProbeNames.begin(), core::kLightProbeNames.end()};
}

ShLight light_probe(const std::string& name) {
  if (name == "grace") return grace_cathedral();
  if (name == "sky") return sky();
  if (name == "sun") return sun();
  if (name == "white") return white_furnace();
  throw std::invalid_argument(fmt::format("light probe '{}' is unknown (expected one of {})", name,
                                          fmt::join(light_probe_names(), ", ")));
}

ShLight directional_light(const Eigen::Vector3d& towards_light, const std::array<double, 3>& rgb) {
  const Eigen::Vector3d s = towards_light.normalized();
  const auto y = core::sh_basis(s.x(), s.y(), s.z());
  ShLight light;
  for (std::size_t c = 0; c < 3; ++c) {
    for (std::size_t k = 0; k < 16; ++k) light.coefficients[c][k] = static_cast<float>(rgb[c] * y[k]);
  }
  return light;
}

ShLight project_light(const std::function<std::array<double, 3>(const Eigen::Vector3d&)>& radiance,
                      int samples) {
  std::array<std::array<double, 16>, 3> sum{};
  const double d_theta = kPi / samples, d_phi = 2 * kPi / (2 * samples);
  for (int i = 0; i < samples; ++i) {
    const double theta = (i + 0.5) * d_theta;
    const double weight = std::sin(theta) * d_theta * d_phi;
    for (int j = 0; j < 2 * samples; ++j) {
      const double phi = (j + 0.5) * d_phi;
      const Eigen::Vector3d w(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                              std::cos(theta));
      const auto L = radiance(w);
      const auto y = core::sh_basis(w.x(), w.y(), w.z());
      for (std::size_t c = 0; c < 3; ++c) {
        for (std::size_t k = 0; k < 16; ++k) sum[c][k] += weight * L[c] * y[k];
      }
    }
  }
  ShLight light;
  for (std::size_t c = 0; c < 3; ++c) {
    for (std::size_t k = 0; k < 16; ++k) light.coefficients[c][k] = static_cast<float>(sum[c][k]);
  }
  return light;
}

Eigen::Matrix<double, 16, 16> sh_rotation(const Eigen::Matrix3d& R) {
  // f_rot(w) = f(R^T w): at each fitting direction d, the rotated function's
  // value is sum_k c_k Y_k(R^T d); fit the coefficients that reproduce it.
  const auto& dirs = fit_directions();
  ShMatrix B(static_cast<Eigen::Index>(dirs.size()), 16);
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    B.row(static_cast<Eigen::Index>(i)) = sh_row(R.transpose() * dirs[i]);
  }
  Eigen::Matrix<double, 16, 16> D = fit_pseudo_inverse() * B;
  // Bands do not mix under rotation; drop round-off outside the blocks.
  for (int a = 0; a < 16; ++a) {
    for (int b = 0; b < 16; ++b) {
      if (core::sh_band(a) != core::sh_band(b)) D(a, b) = 0;
    }
  }
  return D;
}

ShLight light_in_support_frame(const ShLight& world, const Eigen::Matrix3d& R) {
  const Eigen::Matrix<double, 16, 16> D = sh_rotation(R.transpose());
  ShLight out;
  for (std::size_t c = 0; c < 3; ++c) {
    Eigen::Matrix<double, 16, 1> v;
    for (int k = 0; k < 16; ++k) v[k] = world.coefficients[c][static_cast<std::size_t>(k)];
    const Eigen::Matrix<double, 16, 1> r = D * v;
    for (int k = 0; k < 16; ++k) out.coefficients[c][static_cast<std::size_t>(k)] = static_cast<float>(r[k]);
  }
  return out;
}

std::array<double, 3> shade(const float* transfer48, const ShLight& light) {
  std::array<double, 3> rgb{};
  for (std::size_t c = 0; c < 3; ++c) {
    for (std::size_t k = 0; k < 16; ++k) rgb[c] += double(transfer48[16 * c + k]) * light.coefficients[c][k];
  }
  return rgb;
}

std::array<double, 3> diffuse_radiance(const ShLight& light, const Eigen::Vector3d& normal,
                                       const std::array<double, 3>& albedo) {
  const auto y = core::sh_basis(normal.x(), normal.y(), normal.z());
  std::array<double, 3> rgb{};
  for (std::size_t c = 0; c < 3; ++c) {
    double irradiance = 0;
    for (std::size_t k = 0; k < 16; ++k) {
      irradiance +=
          core::clamped_cosine_band(core::sh_band(static_cast<int>(k))) * y[k] * light.coefficients[c][k];
    }
    rgb[c] = albedo[c] / kPi * irradiance;
  }
  return rgb;
}

}  // namespace phasecast::client
