#pragma once
// The static data a thin render client needs (§5.3): mean shape, triangles,
// normals, flags, U_u, mean transfer and U_a, as raw row-major byte views of a
// package. The server streams these in chunks; inspect reports their sizes.
//
// basis_part_specs() is the one table of these parts: the server lists and
// serves them from it, and the client checks what it is sent against it.

#include "phasecast/core/package.h"

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
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

inline constexpr std::size_t kBasisPartCount = 8;

// The scene sizes a part's shape depends on. A package gives them
// (basis_sizes), and so does a SceneInfo on the client, which holds no package.
struct BasisSizes {
  std::uint64_t points = 0;     // S
  std::uint64_t triangles = 0;  // F
  std::uint64_t rank_u = 0;     // r_u
  std::uint64_t rank_a = 0;     // r_a (0: no appearance model)
};

BasisSizes basis_sizes(const ScenePackage& package);

// One row of the basis-part table: what docs/protocol.md promises for a part.
struct BasisPartSpec {
  BasisPartId id;
  std::string_view name;      // e.g. "U_u", the package dataset's name
  std::string_view dtype;     // "float32", "uint32" or "uint8" (little-endian)
  std::size_t element_bytes;  // of one element of `dtype`
  bool needs_appearance;      // listed only when the package has an appearance model
  std::vector<std::uint64_t> (*shape)(const BasisSizes& sizes);
  // The part's data in `package`; for needs_appearance parts, the package must have one.
  std::span<const std::byte> (*bytes)(const ScenePackage& package);
};

// Every part, in BasisPartId order.
std::span<const BasisPartSpec> basis_part_specs();
// The part numbered `id` (a phasecast.v1.BasisPart value), or nullptr when
// there is none: the wire may carry any number.
const BasisPartSpec* find_basis_part_spec(int id);

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
