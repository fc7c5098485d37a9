#include "phasecast/core/mesh_geometry.h"

#include <Eigen/Geometry>

#include <array>
#include <cmath>

namespace phasecast::core {

MatrixXfR vertex_normals(const MatrixXfR& P, const MatrixXuR& F) {
  Eigen::MatrixXd n = Eigen::MatrixXd::Zero(P.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const std::array<Eigen::Vector3d, 3> x{P.row(F(f, 0)).cast<double>().transpose(),
                                           P.row(F(f, 1)).cast<double>().transpose(),
                                           P.row(F(f, 2)).cast<double>().transpose()};
    const Eigen::Vector3d face = (x[1] - x[0]).cross(x[2] - x[0]);
    if (!(face.norm() > 0)) continue;  // degenerate: no direction to contribute
    const Eigen::Vector3d unit = face.normalized();
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d e1 = x[static_cast<size_t>((j + 1) % 3)] - x[static_cast<size_t>(j)];
      const Eigen::Vector3d e2 = x[static_cast<size_t>((j + 2) % 3)] - x[static_cast<size_t>(j)];
      const double angle = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
      n.row(F(f, j)) += angle * unit.transpose();
    }
  }
  MatrixXfR out(P.rows(), 3);
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    const double len = n.row(i).norm();
    if (len > 0) {
      out.row(i) = (n.row(i) / len).cast<float>();
    } else {
      out.row(i) << 0, 0, 1;
    }
  }
  return out;
}

std::vector<std::int64_t> add_back_side(MatrixXfR& positions, MatrixXfR& normals, MatrixXuR& triangles,
                                        const std::vector<int>& back) {
  const Eigen::Index S = positions.rows(), B = static_cast<Eigen::Index>(back.size());
  std::vector<std::int64_t> copy_of(static_cast<size_t>(S), -1);
  positions.conservativeResize(S + B, 3);
  normals.conservativeResize(S + B, 3);
  for (Eigen::Index i = 0; i < B; ++i) {
    const int v = back[static_cast<size_t>(i)];
    copy_of[static_cast<size_t>(v)] = S + i;
    positions.row(S + i) = positions.row(v);
    normals.row(S + i) = -normals.row(v);
  }
  std::vector<std::uint32_t> added;
  for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
    const auto a = copy_of[triangles(t, 0)], b = copy_of[triangles(t, 1)], c = copy_of[triangles(t, 2)];
    if (a < 0 || b < 0 || c < 0) continue;
    // Same corners, reversed winding: the copy's front faces the other way.
    added.insert(added.end(), {static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(c),
                               static_cast<std::uint32_t>(b)});
  }
  const Eigen::Index F = triangles.rows(), count = static_cast<Eigen::Index>(added.size() / 3);
  triangles.conservativeResize(F + count, 3);
  triangles.bottomRows(count) = Eigen::Map<const MatrixXuR>(added.data(), count, 3);
  return copy_of;
}

}  // namespace phasecast::core
