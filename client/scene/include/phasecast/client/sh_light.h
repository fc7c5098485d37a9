#pragma once
// Distant lighting as order-4 spherical harmonics (16 coefficients per colour
// channel, convention of core/sh.h), the light the transfer vectors are dotted
// with (§4). Built-in probes, and the rotation of a light into the support
// frame when the support rotates (transfer is stored in the support frame).

#include "phasecast/core/sh.h"

#include <Eigen/Core>

#include <array>
#include <functional>
#include <string>
#include <vector>

namespace phasecast::client {

// L_k per channel: coefficients[c][k], c = R, G, B.
struct ShLight {
  std::array<core::ShVector, 3> coefficients{};

  // The 48 floats in the transfer layout (channel, k): index 16c + k.
  std::array<float, 48> packed() const;
};

// Names accepted by light_probe(): "grace" (Grace Cathedral, Ramamoorthi &
// Hanrahan 2001, y up), "sky" (bright sky above a dark ground, y up), "sun"
// (a directional light from above-front plus a dim sky), "white" (constant
// radiance 1: the white furnace).
std::vector<std::string> light_probe_names();

// Throws std::invalid_argument for unknown names, listing the known ones.
ShLight light_probe(const std::string& name);

// A directional light of irradiance `rgb` (W/m^2 at normal incidence) from
// unit direction `towards_light`: the delta function's projection E Y_k(s).
ShLight directional_light(const Eigen::Vector3d& towards_light, const std::array<double, 3>& rgb);

// Projects radiance(direction) -> RGB with a deterministic spherical
// quadrature (`samples` per axis of a theta/phi product rule).
ShLight project_light(const std::function<std::array<double, 3>(const Eigen::Vector3d&)>& radiance,
                      int samples = 128);

// 16 x 16 block-diagonal matrix D with (D c) the coefficients of
// f(R^T w), f having coefficients c: the function rotated by R. Exact for
// band-limited f (bands 0..3 are closed under rotation); computed by fitting
// at fixed directions.
Eigen::Matrix<double, 16, 16> sh_rotation(const Eigen::Matrix3d& R);

// The light a point in the support frame sees when the support's rotation
// (support frame -> world) is R: L_s(w) = L_world(R w), i.e. rotated by R^T.
ShLight light_in_support_frame(const ShLight& world, const Eigen::Matrix3d& R);

// Exit radiance sum_k T_k L_k of one transfer vector (48 floats) per channel.
std::array<double, 3> shade(const float* transfer48, const ShLight& light);

// Exit radiance of an unshadowed diffuse surface of reflectance `albedo`
// with unit normal `normal`: (albedo / pi) sum_k A_l Y_k(normal) L_k
// (Ramamoorthi & Hanrahan 2001; A_3 = 0), the irradiance formula of
// shaders/low_rank.vert's fallback. Lights the backdrop's ground.
std::array<double, 3> diffuse_radiance(const ShLight& light, const Eigen::Vector3d& normal,
                                       const std::array<double, 3>& albedo);

}  // namespace phasecast::client
