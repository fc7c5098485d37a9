#include "phasecast/core/basis.h"

#include <algorithm>
#include <array>

namespace phasecast::core {
namespace {

using Shape = std::vector<std::uint64_t>;

// Raw view of an Eigen matrix or std::vector: row-major storage is the wire layout.
template <class Container>
std::span<const std::byte> bytes_of(const Container& c) {
  return std::as_bytes(std::span(c.data(), static_cast<std::size_t>(c.size())));
}

std::uint64_t u64(Eigen::Index v) {
  return static_cast<std::uint64_t>(v);
}

// A shape from scene sizes and constants, short enough to keep a table row readable.
template <class... Dims>
Shape dims(Dims... d) {
  return {static_cast<std::uint64_t>(d)...};
}

// docs/protocol.md "Basis download" in code; keep the two in step.
constexpr std::array<BasisPartSpec, kBasisPartCount> kParts = {{
    {BasisPartId::mean_shape, "mean_shape", "float32", 4, false,  // x_bar, eq. 7
     [](const BasisSizes& s) { return dims(s.points, 3); },
     [](const ScenePackage& p) { return bytes_of(p.reduction.mean_shape); }},
    {BasisPartId::triangles, "triangles", "uint32", 4, false,  // point indices
     [](const BasisSizes& s) { return dims(s.triangles, 3); },
     [](const ScenePackage& p) { return bytes_of(p.mesh.triangles); }},
    {BasisPartId::normals, "normals", "float32", 4, false,  // rest normals
     [](const BasisSizes& s) { return dims(s.points, 3); },
     [](const ScenePackage& p) { return bytes_of(p.mesh.normals); }},
    {BasisPartId::deformable, "deformable", "uint8", 1, false,  // 1 = moved by U_u
     [](const BasisSizes& s) { return dims(s.points); },
     [](const ScenePackage& p) { return bytes_of(p.mesh.deformable); }},
    {BasisPartId::attached, "attached", "uint8", 1, false,  // 1 = moves with the support transform
     [](const BasisSizes& s) { return dims(s.points); },
     [](const ScenePackage& p) { return bytes_of(p.mesh.attached); }},
    {BasisPartId::U_u, "U_u", "float32", 4, false,  // row-major, eq. 7
     [](const BasisSizes& s) { return dims(3 * s.points, s.rank_u); },
     [](const ScenePackage& p) { return bytes_of(p.reduction.U_u); }},
    {BasisPartId::mean_transfer, "mean_transfer", "float32", 4, true,  // M_bar, §4.2
     [](const BasisSizes& s) { return dims(kTransferPerPoint * s.points); },
     [](const ScenePackage& p) { return bytes_of(p.appearance->mean_transfer); }},
    {BasisPartId::U_a, "U_a", "float32", 4, true,  // row-major
     [](const BasisSizes& s) { return dims(kTransferPerPoint * s.points, s.rank_a); },
     [](const ScenePackage& p) { return bytes_of(p.appearance->U_a); }},
}};

}  // namespace

BasisSizes basis_sizes(const ScenePackage& p) {
  return {u64(p.mesh.rest_positions.rows()), u64(p.mesh.triangles.rows()), u64(p.reduction.U_u.cols()),
          p.appearance ? u64(p.appearance->U_a.cols()) : 0};
}

std::span<const BasisPartSpec> basis_part_specs() {
  return kParts;
}

const BasisPartSpec* find_basis_part_spec(int id) {
  const auto it = std::find_if(kParts.begin(), kParts.end(),
                               [&](const BasisPartSpec& s) { return static_cast<int>(s.id) == id; });
  return it == kParts.end() ? nullptr : &*it;
}

std::vector<BasisPartView> basis_parts(const ScenePackage& p) {
  const BasisSizes sizes = basis_sizes(p);
  std::vector<BasisPartView> parts;
  for (const auto& spec : kParts) {
    if (spec.needs_appearance && !p.appearance) continue;
    parts.push_back(
        {spec.id, std::string(spec.name), std::string(spec.dtype), spec.shape(sizes), spec.bytes(p)});
  }
  return parts;
}

std::uint64_t reduced_state_bytes(const ScenePackage& p) {
  return sizeof(float) * static_cast<std::uint64_t>(p.rank_u() + p.rank_a() + kSupportFloats);
}

std::uint64_t full_vertex_bytes(const ScenePackage& p) {
  // Streaming the synthesized result instead: a position per scene point, and
  // an RGB exit radiance per point when the scene has an appearance model.
  const std::uint64_t per_point = p.appearance ? 6 : 3;
  return sizeof(float) * per_point * u64(p.mesh.rest_positions.rows());
}

}  // namespace phasecast::core
