#include "phasecast/precompute/simulation/deformable_model.h"

#include "phasecast/precompute/simulation/elastic_forces.h"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <utility>

namespace phasecast::precompute {
namespace {

Eigen::Vector3d rest_point(const DeformableModel& m, int i) {
  return m.rest.segment<3>(3 * i);
}

void check_index(const DeformableModel& m, int i, const char* what) {
  if (i < 0 || 3 * i + 2 >= m.rest.size()) {
    throw std::invalid_argument(
        fmt::format("{}: vertex index {} out of range [0, {})", what, i, m.rest.size() / 3));
  }
}

}  // namespace

Lame lame_from_young(double young, double poisson) {
  if (!(young > 0) || !(poisson >= 0 && poisson < 0.5)) {
    throw std::invalid_argument(fmt::format(
        "material: expected young > 0 and 0 <= poisson < 0.5, got young={} poisson={}", young, poisson));
  }
  return {young / (2 * (1 + poisson)), young * poisson / ((1 + poisson) * (1 - 2 * poisson))};
}

void add_membrane(DeformableModel& model, std::array<int, 3> v, Lame lame) {
  for (int i : v) check_index(model, i, "membrane");
  const Eigen::Vector3d e1 = rest_point(model, v[1]) - rest_point(model, v[0]);
  const Eigen::Vector3d e2 = rest_point(model, v[2]) - rest_point(model, v[0]);
  const Eigen::Vector3d n = e1.cross(e2);
  const double area = 0.5 * n.norm();
  if (!(area > 1e-14)) {
    throw std::invalid_argument(
        fmt::format("membrane triangle ({}, {}, {}) is degenerate (zero area)", v[0], v[1], v[2]));
  }
  // Rest edges in the triangle's own orthonormal 2D frame (b1 along e1).
  const Eigen::Vector3d b1 = e1.normalized();
  const Eigen::Vector3d b2 = n.normalized().cross(b1);
  Eigen::Matrix2d Dm;
  Dm << e1.norm(), e2.dot(b1), 0.0, e2.dot(b2);
  model.membranes.push_back({v, Dm.inverse(), area, lame});
}

void add_hinge(DeformableModel& model, std::array<int, 4> v, double bending_modulus) {
  for (int i : v) check_index(model, i, "hinge");
  const auto x = [&](int k) { return rest_point(model, v[static_cast<size_t>(k)]); };
  const Eigen::Vector3d e = x(1) - x(0);
  const double a1 = 0.5 * e.cross(x(2) - x(0)).norm();
  const double a2 = 0.5 * e.cross(x(3) - x(0)).norm();
  if (!(a1 > 1e-14 && a2 > 1e-14)) {
    throw std::invalid_argument(fmt::format("hinge on edge ({}, {}) has a degenerate triangle", v[0], v[1]));
  }
  // Discrete shells: |e| / h-bar with h-bar = (A1 + A2) / (3 |e|).
  const double stiffness = bending_modulus * 3.0 * e.squaredNorm() / (a1 + a2);
  model.hinges.push_back({v, dihedral_angle(x(0), x(1), x(2), x(3)), stiffness});
}

namespace {
RodStretchElement axial_spring(const DeformableModel& model, int a, int b, double ea, const char* what) {
  check_index(model, a, what);
  check_index(model, b, what);
  const double l0 = (rest_point(model, b) - rest_point(model, a)).norm();
  if (!(l0 > 1e-9)) throw std::invalid_argument(fmt::format("{} edge ({}, {}) has zero length", what, a, b));
  return {a, b, l0, ea / l0};
}
}  // namespace

void add_rod_stretch(DeformableModel& model, int a, int b, double ea) {
  model.rod_stretch.push_back(axial_spring(model, a, b, ea, "rod"));
}

void add_brace(DeformableModel& model, int a, int b, double ea) {
  model.braces.push_back(axial_spring(model, a, b, ea, "brace"));
}

void add_rod_bend(DeformableModel& model, int a, int b, int c, double ei) {
  check_index(model, a, "rod");
  check_index(model, b, "rod");
  check_index(model, c, "rod");
  const Eigen::Vector3d e1 = rest_point(model, b) - rest_point(model, a);
  const Eigen::Vector3d e2 = rest_point(model, c) - rest_point(model, b);
  if (!(e1.norm() > 1e-9 && e2.norm() > 1e-9)) {
    throw std::invalid_argument(fmt::format("rod joint ({}, {}, {}) has a zero-length edge", a, b, c));
  }
  const double l_bar = 0.5 * (e1.norm() + e2.norm());
  const double c0 = (e2.normalized() - e1.normalized()).norm();
  model.rod_bend.push_back({a, b, c, c0, ei / l_bar});
}

void add_tet(DeformableModel& model, std::array<int, 4> v, Lame lame, TetEnergy energy) {
  for (int i : v) check_index(model, i, "tet");
  Eigen::Matrix3d Dm;
  for (int k = 0; k < 3; ++k) {
    Dm.col(k) = rest_point(model, v[static_cast<size_t>(k + 1)]) - rest_point(model, v[0]);
  }
  const double volume = Dm.determinant() / 6.0;
  if (volume < 0) {
    throw std::invalid_argument(
        fmt::format("tet ({}, {}, {}, {}) is inverted (volume {} < 0)", v[0], v[1], v[2], v[3], volume));
  }
  if (!(volume > 1e-18)) {
    throw std::invalid_argument(
        fmt::format("tet ({}, {}, {}, {}) is degenerate (zero volume)", v[0], v[1], v[2], v[3]));
  }
  model.tets.push_back({v, Dm.inverse(), volume, lame, energy});
}

std::vector<std::array<int, 4>> mesh_hinges(const Eigen::MatrixXi& triangles) {
  // Directed edge (a, b) of triangle t -> opposite vertex; a hinge joins (a, b) and (b, a).
  std::map<std::pair<int, int>, int> opposite;
  for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = triangles(t, k), b = triangles(t, (k + 1) % 3), c = triangles(t, (k + 2) % 3);
      opposite[{a, b}] = c;
    }
  }
  std::vector<std::array<int, 4>> hinges;
  for (const auto& [edge, c] : opposite) {
    const auto twin = opposite.find({edge.second, edge.first});
    if (twin != opposite.end() && edge.first < edge.second) {
      hinges.push_back({edge.first, edge.second, c, twin->second});
    }
  }
  return hinges;
}

}  // namespace phasecast::precompute
