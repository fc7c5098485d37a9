#include "phasecast/precompute/simulation/embedding.h"

#include "box_hash.h"
#include "phasecast/precompute/simulation/self_collision.h"

#include <fmt/format.h>

#include <Eigen/Dense>

#include <array>
#include <limits>
#include <map>
#include <stdexcept>
#include <vector>

namespace phasecast::precompute {
namespace {

// Rounding slack of "inside": a point on a shared face belongs to either tet.
constexpr double kInside = -1e-9;

struct TetGeometry {
  const Eigen::VectorXd& rest;
  const Eigen::MatrixX4i& tets;
  std::vector<Eigen::Matrix3d> inverse;  // of [x1 - x0, x2 - x0, x3 - x0]

  Eigen::Vector3d corner(Eigen::Index t, int k) const { return rest.segment<3>(3 * tets(t, k)); }

  // Barycentric weights of p in tet t (any p: outside, some are negative).
  Eigen::Vector4d barycentric(Eigen::Index t, const Eigen::Vector3d& p) const {
    const Eigen::Vector3d l = inverse[static_cast<size_t>(t)] * (p - corner(t, 0));
    return {1 - l.sum(), l.x(), l.y(), l.z()};
  }
};

TetGeometry tet_geometry(const Eigen::VectorXd& rest, const Eigen::MatrixX4i& tets) {
  TetGeometry g{rest, tets, {}};
  for (Eigen::Index t = 0; t < tets.rows(); ++t) {
    Eigen::Matrix3d D;
    for (int k = 0; k < 3; ++k) D.col(k) = g.corner(t, k + 1) - g.corner(t, 0);
    if (!(std::abs(D.determinant()) > 0)) throw std::invalid_argument(fmt::format("tet {} is degenerate", t));
    g.inverse.push_back(D.inverse());
  }
  return g;
}

std::array<int, 3> sorted(int a, int b, int c) {
  std::array<int, 3> f{a, b, c};
  std::sort(f.begin(), f.end());
  return f;
}

// The tet behind each boundary triangle (-1 when the triangle is no tet's face).
std::vector<int> boundary_tets(const Eigen::MatrixX4i& tets, const Eigen::MatrixXi& boundary) {
  std::map<std::array<int, 3>, int> face_tet;
  for (Eigen::Index t = 0; t < tets.rows(); ++t)
    for (int k = 0; k < 4; ++k)
      face_tet[sorted(tets(t, (k + 1) % 4), tets(t, (k + 2) % 4), tets(t, (k + 3) % 4))] =
          static_cast<int>(t);
  std::vector<int> out;
  for (Eigen::Index b = 0; b < boundary.rows(); ++b) {
    const auto it = face_tet.find(sorted(boundary(b, 0), boundary(b, 1), boundary(b, 2)));
    out.push_back(it == face_tet.end() ? -1 : it->second);
  }
  return out;
}

// The tet containing p, or -1.
int containing_tet(const TetGeometry& g, const BoxHash& hash, const Eigen::Vector3d& p) {
  int best = -1;
  double best_min = kInside;
  for (int t : hash.overlapping(Eigen::AlignedBox3d(p, p))) {
    const double m = g.barycentric(t, p).minCoeff();
    if (m >= best_min) best = t, best_min = m;
  }
  return best;
}

struct Nearest {
  int tet = -1;
  double distance = std::numeric_limits<double>::infinity();
};

// The tet behind the boundary triangle nearest p, among those within `radius`.
Nearest nearest_boundary(const TetGeometry& g, const Eigen::MatrixXi& boundary,
                         const std::vector<int>& behind, const BoxHash& hash, const Eigen::Vector3d& p,
                         double radius) {
  Nearest n;
  const Eigen::Vector3d r = Eigen::Vector3d::Constant(radius);
  for (int b : hash.overlapping(Eigen::AlignedBox3d(p - r, p + r))) {
    if (behind[static_cast<size_t>(b)] < 0) continue;
    std::array<Eigen::Vector3d, 3> x;
    for (int k = 0; k < 3; ++k) x[static_cast<size_t>(k)] = g.rest.segment<3>(3 * boundary(b, k));
    const Eigen::Vector3d w = closest_barycentric(p, x[0], x[1], x[2]);
    const double d = (p - (w[0] * x[0] + w[1] * x[1] + w[2] * x[2])).norm();
    if (d < n.distance) n = {behind[static_cast<size_t>(b)], d};
  }
  return n;
}

std::vector<Eigen::AlignedBox3d> tet_boxes(const TetGeometry& g) {
  std::vector<Eigen::AlignedBox3d> boxes;
  for (Eigen::Index t = 0; t < g.tets.rows(); ++t) {
    Eigen::AlignedBox3d box;
    for (int k = 0; k < 4; ++k) box.extend(g.corner(t, k));
    boxes.push_back(box);
  }
  return boxes;
}

std::vector<Eigen::AlignedBox3d> triangle_boxes(const Eigen::VectorXd& rest,
                                                const Eigen::MatrixXi& triangles) {
  std::vector<Eigen::AlignedBox3d> boxes;
  for (Eigen::Index b = 0; b < triangles.rows(); ++b) {
    Eigen::AlignedBox3d box;
    for (int k = 0; k < 3; ++k) box.extend(Eigen::Vector3d(rest.segment<3>(3 * triangles(b, k))));
    boxes.push_back(box);
  }
  return boxes;
}

}  // namespace

VertexEmbedding tet_embedding(const Eigen::MatrixX3d& points, const Eigen::VectorXd& rest,
                              const Eigen::MatrixX4i& tets, const Eigen::MatrixXi& boundary,
                              double max_outside) {
  const TetGeometry g = tet_geometry(rest, tets);
  const auto tet_box = tet_boxes(g), face_box = triangle_boxes(rest, boundary);
  const BoxHash in_tets(tet_box), on_boundary(face_box);
  const auto behind = boundary_tets(tets, boundary);
  std::vector<Eigen::Triplet<double>> w;
  for (Eigen::Index p = 0; p < points.rows(); ++p) {
    const Eigen::Vector3d x = points.row(p).transpose();
    int t = containing_tet(g, in_tets, x);
    if (t < 0) {
      const Nearest n = nearest_boundary(g, boundary, behind, on_boundary, x, max_outside);
      if (n.tet < 0 || n.distance > max_outside) {
        throw std::invalid_argument(fmt::format(
            "render vertex {} at ({:.4g}, {:.4g}, {:.4g}) lies {} outside the tets (expected within "
            "{:.3g} m of the surface)",
            p, x.x(), x.y(), x.z(),
            n.tet < 0 ? fmt::format("more than {:.3g} m", max_outside) : fmt::format("{:.3g} m", n.distance),
            max_outside));
      }
      t = n.tet;
    }
    const Eigen::Vector4d b = g.barycentric(t, x);
    for (int k = 0; k < 4; ++k) w.emplace_back(static_cast<int>(p), tets(t, k), b[k]);
  }
  VertexEmbedding W(points.rows(), rest.size() / 3);
  W.setFromTriplets(w.begin(), w.end());
  return W;
}

}  // namespace phasecast::precompute
