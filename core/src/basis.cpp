#include "phasecast/core/basis.h"

namespace phasecast::core {
namespace {

template <class T>
std::span<const std::byte> bytes_of(const T* data, std::size_t count) {
  return {reinterpret_cast<const std::byte*>(data), count * sizeof(T)};
}

std::uint64_t u64(Eigen::Index v) {
  return static_cast<std::uint64_t>(v);
}

}  // namespace

std::vector<BasisPartView> basis_parts(const ScenePackage& p) {
  const auto& m = p.mesh;
  const auto S = u64(m.rest_positions.rows());
  std::vector<BasisPartView> parts = {
      {BasisPartId::mean_shape,
       "mean_shape",
       "float32",
       {S, 3},
       bytes_of(p.reduction.mean_shape.data(), static_cast<std::size_t>(p.reduction.mean_shape.size()))},
      {BasisPartId::triangles,
       "triangles",
       "uint32",
       {u64(m.triangles.rows()), 3},
       bytes_of(m.triangles.data(), static_cast<std::size_t>(m.triangles.size()))},
      {BasisPartId::normals,
       "normals",
       "float32",
       {S, 3},
       bytes_of(m.normals.data(), static_cast<std::size_t>(m.normals.size()))},
      {BasisPartId::deformable,
       "deformable",
       "uint8",
       {S},
       bytes_of(m.deformable.data(), m.deformable.size())},
      {BasisPartId::attached, "attached", "uint8", {S}, bytes_of(m.attached.data(), m.attached.size())},
      {BasisPartId::U_u,
       "U_u",
       "float32",
       {3 * S, u64(p.reduction.U_u.cols())},
       bytes_of(p.reduction.U_u.data(), static_cast<std::size_t>(p.reduction.U_u.size()))},
  };
  if (const auto& a = p.appearance) {
    parts.push_back({BasisPartId::mean_transfer,
                     "mean_transfer",
                     "float32",
                     {48 * S},
                     bytes_of(a->mean_transfer.data(), static_cast<std::size_t>(a->mean_transfer.size()))});
    parts.push_back({BasisPartId::U_a,
                     "U_a",
                     "float32",
                     {48 * S, u64(a->U_a.cols())},
                     bytes_of(a->U_a.data(), static_cast<std::size_t>(a->U_a.size()))});
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
