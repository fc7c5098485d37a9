#pragma once
// What a thin client holds (§5.3): the mean shape x_bar, triangles, rest
// normals, point flags, U_u, the mean transfer M_bar and U_a. It comes either
// from a package file (local mode) or from the server in chunks (network
// mode, docs/protocol.md "Basis download"); both paths end in validate().

#include "phasecast/core/package.h"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::client {

struct ClientBasis {
  std::string scene;
  std::uint64_t content_hash = 0;               // of the package file the bases came from
  int points = 0;                               // S
  int rank_u = 0;                               // r_u
  int rank_a = 0;                               // r_a (0: no appearance model)
  std::vector<float> mean_shape;                // 3S, x_bar (eq. 7)
  std::vector<std::uint32_t> triangles;         // 3F
  std::vector<float> normals;                   // 3S rest normals
  std::vector<std::uint8_t> deformable;         // S
  std::vector<std::uint8_t> attached;           // S
  std::vector<float> U_u;                       // 3S x r_u row-major
  std::vector<float> mean_transfer;             // 48S (empty when r_a == 0 and no transfer)
  std::vector<float> U_a;                       // 48S x r_a row-major
  std::optional<std::array<float, 10>> camera;  // eye, target, up, fov_y_deg
  // The rest of the scene's view (core::PackageAttributes): used where the
  // client's own flags are absent.
  bool floor = true;
  std::optional<float> floor_height;  // absent: under the rest mesh's lowest point
  std::string light;                  // empty: the client's default
  std::optional<float> exposure;

  int triangle_count() const { return static_cast<int>(triangles.size() / 3); }
  bool has_transfer() const { return !mean_transfer.empty(); }

  // Checks sizes against S, r_u, r_a, triangle indices < S, finite floats.
  // Throws std::invalid_argument naming `source`, the part and what was expected.
  void validate(const std::string& source) const;
};

// The package's view (camera, floor, light, exposure) onto `basis`.
void set_view(ClientBasis& basis, const core::PackageAttributes& attributes);

// The bases of a package held in memory (local mode, tests).
ClientBasis basis_from_package(const core::ScenePackage& package, std::uint64_t content_hash);

// Positions x = x_bar + U_u q_u (eq. 7), then the support transform for
// attached points, on the CPU in double precision: the reference the GPU
// result is checked against. `support` is 3x4 row-major (empty: identity).
std::vector<double> cpu_positions(const ClientBasis& basis, const std::vector<float>& q_u,
                                  const std::vector<float>& support);

}  // namespace phasecast::client
