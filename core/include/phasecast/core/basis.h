#pragma once
// The static data a thin render client needs (§5.3): mean shape, triangles,
// normals, flags, U_u, mean transfer and U_a, as raw row-major byte views of a
// package. The server streams these in chunks; inspect reports their sizes.

#include "phasecast/core/package.h"

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace phasecast::core {

// Numbers match phasecast.v1.BasisPart.
enum class BasisPartId : int {
  mean_shape = 1,
  triangles = 2,
  normals = 3,
  deformable = 4,
  attached = 5,
  U_u = 6,
  mean_transfer = 7,
  U_a = 8,
};

struct BasisPartView {
  BasisPartId id;
  std::string name;   // e.g. "U_u"
  std::string dtype;  // "float32", "uint32" or "uint8"
  std::vector<std::uint64_t> shape;
  std::span<const std::byte> bytes;  // points into the package; valid while it lives
};

// Every part a thin client downloads, in BasisPartId order; the appearance
// parts are present only when the package has an appearance model.
std::vector<BasisPartView> basis_parts(const ScenePackage& package);

// Bytes one published Frame carries for this scene's reduced state
// (q_u, q_a, support) and, for comparison, what streaming the synthesized
// result would cost: positions (plus RGB colours when there is appearance).
std::uint64_t reduced_state_bytes(const ScenePackage& package);
std::uint64_t full_vertex_bytes(const ScenePackage& package);

}  // namespace phasecast::core
