#include "phasecast/precompute/simulation/self_collision.h"

#include "box_hash.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <set>
#include <unordered_map>
#include <utility>

namespace phasecast::precompute {
namespace {

using Eigen::Vector3d;

Vector3d point(const Eigen::VectorXd& x, int i) {
  return x.segment<3>(3 * i);
}

double orient(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  return (b - a).cross(c - a).dot(d - a);
}

// Segment pq against closed triangle abc.
bool segment_hits_triangle(const Vector3d& p, const Vector3d& q, const Vector3d& a, const Vector3d& b,
                           const Vector3d& c) {
  const double sp = orient(a, b, c, p), sq = orient(a, b, c, q);
  if ((sp > 0 && sq > 0) || (sp < 0 && sq < 0)) return false;
  if (sp == 0 && sq == 0)
    return false;  // coplanar: counted by the other triangle's edges or not an overlap we track
  const double s1 = orient(p, q, a, b), s2 = orient(p, q, b, c), s3 = orient(p, q, c, a);
  return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

}  // namespace

Vector3d closest_barycentric(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  // Ericson, Real-Time Collision Detection, 5.1.5.
  const Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double t = d1 / (d1 - d3);
    return {1 - t, t, 0};
  }
  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double t = d2 / (d2 - d6);
    return {1 - t, 0, t};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - t, t};
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}

// Ericson, Real-Time Collision Detection, 5.1.9.
std::pair<double, double> closest_segment_params(const Vector3d& p0, const Vector3d& p1, const Vector3d& q0,
                                                 const Vector3d& q1) {
  const Vector3d d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  const double c = d1.dot(r), b = d1.dot(d2), denom = a * e - b * b;
  double s = denom > 1e-20 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
  double t = (b * s + f) / e;
  if (t < 0) {
    t = 0;
    s = std::clamp(-c / a, 0.0, 1.0);
  } else if (t > 1) {
    t = 1;
    s = std::clamp((b - c) / a, 0.0, 1.0);
  }
  return {s, t};
}

bool triangles_intersect(const std::array<Vector3d, 3>& t, const std::array<Vector3d, 3>& u) {
  for (int e = 0; e < 3; ++e) {
    if (segment_hits_triangle(t[static_cast<size_t>(e)], t[static_cast<size_t>((e + 1) % 3)], u[0], u[1],
                              u[2]))
      return true;
    if (segment_hits_triangle(u[static_cast<size_t>(e)], u[static_cast<size_t>((e + 1) % 3)], t[0], t[1],
                              t[2]))
      return true;
  }
  return false;
}

int count_intersecting_pairs(const Eigen::VectorXd& x, const Eigen::MatrixXi& tris) {
  const auto corners = [&](Eigen::Index f) {
    return std::array<Vector3d, 3>{point(x, tris(f, 0)), point(x, tris(f, 1)), point(x, tris(f, 2))};
  };
  std::vector<Eigen::AlignedBox3d> boxes;
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    const auto t = corners(f);
    boxes.push_back(Eigen::AlignedBox3d(t[0]).extend(t[1]).extend(t[2]));
  }
  const BoxHash hash(boxes);
  int count = 0;
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    const auto t = corners(f);
    for (int g : hash.overlapping(boxes[static_cast<size_t>(f)])) {
      if (g <= f) continue;
      bool shared = false;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) shared |= tris(f, a) == tris(g, b);
      if (!shared && triangles_intersect(t, corners(g))) ++count;
    }
  }
  return count;
}

std::vector<std::array<int, 2>> surface_edges(const Eigen::MatrixXi& triangles) {
  std::set<std::array<int, 2>> unique;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = triangles(f, k), b = triangles(f, (k + 1) % 3);
      unique.insert({std::min(a, b), std::max(a, b)});
    }
  }
  return {unique.begin(), unique.end()};
}

namespace {

// Smallest distance between surface vertices that share no triangle, and
// whether any pair is nearer than `close` (vertices hashed into cells of that
// size). Only the surface collides: a rod's or a brace's vertex numbered
// among the surface's is not one of its points.
double closest_non_neighbours(const Eigen::VectorXd& x, const std::set<std::pair<int, int>>& neighbours,
                              const std::vector<int>& surface, double close) {
  std::vector<Eigen::AlignedBox3d> boxes;
  for (int v : surface)
    boxes.emplace_back(point(x, v).array() - 0.5 * close, point(x, v).array() + 0.5 * close);
  const BoxHash hash(boxes);
  double closest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < surface.size(); ++i) {
    for (int j : hash.overlapping(boxes[i])) {
      const int v = surface[i], u = surface[static_cast<std::size_t>(j)];
      if (u <= v || neighbours.count({v, u})) continue;
      closest = std::min(closest, (point(x, v) - point(x, u)).norm());
    }
  }
  return closest;
}

// Smallest distance from a surface vertex to a triangle not incident to it,
// as the self-collision measures it, if at most `reach` (else infinite).
double closest_vertex_triangle(const Eigen::VectorXd& x, const Eigen::MatrixXi& triangles,
                               const std::vector<int>& surface, double reach) {
  std::vector<Eigen::AlignedBox3d> boxes;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    Eigen::AlignedBox3d box(point(x, triangles(f, 0)));
    box.extend(point(x, triangles(f, 1))).extend(point(x, triangles(f, 2)));
    boxes.emplace_back(box.min().array() - reach, box.max().array() + reach);
  }
  const BoxHash hash(boxes);
  double closest = std::numeric_limits<double>::infinity();  // beyond reach
  for (int v : surface) {
    const Vector3d p = point(x, v);
    for (int f : hash.overlapping(Eigen::AlignedBox3d(p, p))) {
      const std::array<int, 3> t = {triangles(f, 0), triangles(f, 1), triangles(f, 2)};
      if (t[0] == v || t[1] == v || t[2] == v) continue;
      const Vector3d w = closest_barycentric(p, point(x, t[0]), point(x, t[1]), point(x, t[2]));
      const double d = (p - (w[0] * point(x, t[0]) + w[1] * point(x, t[1]) + w[2] * point(x, t[2]))).norm();
      if (d <= reach) closest = std::min(closest, d);
    }
  }
  return closest;
}

}  // namespace

ContactSummary summarize_contact(const MatrixXfR& positions, const Eigen::MatrixXi& triangles,
                                 double close_distance, double thickness) {
  std::set<std::pair<int, int>> neighbours;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) neighbours.insert({triangles(f, a), triangles(f, b)});
  std::set<int> on_surface(triangles.data(), triangles.data() + triangles.size());
  const std::vector<int> surface(on_surface.begin(), on_surface.end());
  const double held = kHeldContact * thickness;
  ContactSummary s;
  s.frames = static_cast<int>(positions.rows());
  s.closest = std::numeric_limits<double>::infinity();
  s.closest_to_triangle = std::numeric_limits<double>::infinity();
  for (Eigen::Index f = 0; f < positions.rows(); ++f) {
    const Eigen::VectorXd x = positions.row(f).cast<double>().transpose();
    const int pairs = count_intersecting_pairs(x, triangles);
    s.frames_intersecting += pairs > 0;
    s.worst_intersecting = std::max(s.worst_intersecting, pairs);
    const double closest = closest_non_neighbours(x, neighbours, surface, close_distance);
    s.frames_close += closest < close_distance;
    s.closest = std::min(s.closest, closest);
    const double touching = closest_vertex_triangle(x, triangles, surface, std::max(held, close_distance));
    s.frames_in_contact += touching < held;
    s.closest_to_triangle = std::min(s.closest_to_triangle, touching);
  }
  return s;
}

SelfCollision::SelfCollision(Eigen::MatrixXi triangles, double thickness, double friction, int sweeps)
    : triangles_(std::move(triangles)), thickness_(thickness), friction_(friction), sweeps_(sweeps) {
  vertex_count_ = triangles_.size() ? triangles_.maxCoeff() + 1 : 0;
  edges_ = surface_edges(triangles_);
}

namespace {

Eigen::AlignedBox3d swept_box(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1,
                              std::initializer_list<int> vs, double pad) {
  Eigen::AlignedBox3d box;
  for (int v : vs) box.extend(point(x0, v)).extend(point(x1, v));
  box.min().array() -= pad;
  box.max().array() += pad;
  return box;
}

}  // namespace

SelfCollision::Pairs SelfCollision::candidates(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) const {
  Pairs pairs;
  std::vector<Eigen::AlignedBox3d> tri_boxes, edge_boxes;
  for (Eigen::Index f = 0; f < triangles_.rows(); ++f) {
    tri_boxes.push_back(
        swept_box(x0, x1, {triangles_(f, 0), triangles_(f, 1), triangles_(f, 2)}, thickness_));
  }
  for (const auto& e : edges_) edge_boxes.push_back(swept_box(x0, x1, {e[0], e[1]}, thickness_));
  const BoxHash tri_hash(tri_boxes), edge_hash(edge_boxes);
  std::vector<int> near;
  for (int v = 0; v < vertex_count_; ++v) {
    tri_hash.overlapping(swept_box(x0, x1, {v}, 0.0), near);
    for (int f : near) {
      if (triangles_(f, 0) != v && triangles_(f, 1) != v && triangles_(f, 2) != v)
        pairs.vertex_triangle.push_back({v, f});
    }
  }
  for (size_t e = 0; e < edges_.size(); ++e) {
    edge_hash.overlapping(edge_boxes[e], near);
    for (int g : near) {
      const auto& a = edges_[e];
      const auto& b = edges_[static_cast<size_t>(g)];
      if (static_cast<size_t>(g) > e && a[0] != b[0] && a[0] != b[1] && a[1] != b[0] && a[1] != b[1]) {
        pairs.edge_edge.push_back({static_cast<int>(e), g});
      }
    }
  }
  return pairs;
}

// Inelastic impulse between two points given as weighted vertex sets, along n
// (pointing from the second to the first), so that their predicted distance after
// h stays at least `thickness`; with friction, a tangential one too. Returns
// whether velocities changed.
bool SelfCollision::repel(const std::array<int, 4>& idx, const std::array<double, 4>& weight,
                          const Vector3d& n, double d0, Eigen::VectorXd& v, double h,
                          const Eigen::VectorXd& inverse_mass) const {
  Vector3d relative = Vector3d::Zero();
  double vn = 0, inv = 0;
  for (size_t k = 0; k < 4; ++k) {
    if (weight[k] == 0) continue;
    relative += weight[k] * point(v, idx[k]);
    vn += weight[k] * point(v, idx[k]).dot(n);
    inv += weight[k] * weight[k] * inverse_mass[idx[k]];
  }
  const double target = std::max(0.0, thickness_ - d0) / h;
  if (d0 + h * vn >= thickness_ || vn >= target || inv <= 0) return false;
  const double impulse = (target - vn) / inv;
  // Coulomb's cone: the tangential relative velocity loses at most friction x
  // the normal change, and stops rather than reverses.
  const Vector3d tangential = relative - vn * n;
  const double slide = tangential.norm();
  Vector3d tangential_impulse = Vector3d::Zero();
  if (friction_ > 0 && slide > 0)
    tangential_impulse = -std::min(1.0, friction_ * (target - vn) / slide) / inv * tangential;
  for (size_t k = 0; k < 4; ++k) {
    const int i = idx[k];
    v.segment<3>(3 * i) += impulse * weight[k] * inverse_mass[i] * n;
    if (friction_ > 0) v.segment<3>(3 * i) += weight[k] * inverse_mass[i] * tangential_impulse;
  }
  return true;
}

void SelfCollision::filter(const Eigen::VectorXd& x0, Eigen::VectorXd& v, double h,
                           const Eigen::VectorXd& inverse_mass) const {
  if (triangles_.rows() == 0) return;
  const Pairs pairs = candidates(x0, x0 + h * v);
  for (int sweep = 0; sweep < sweeps_; ++sweep) {
    bool changed = false;
    for (const auto& [p, f] : pairs.vertex_triangle) {
      const std::array<int, 3> t = {triangles_(f, 0), triangles_(f, 1), triangles_(f, 2)};
      const Vector3d w = closest_barycentric(point(x0, p), point(x0, t[0]), point(x0, t[1]), point(x0, t[2]));
      const Vector3d q0 = w[0] * point(x0, t[0]) + w[1] * point(x0, t[1]) + w[2] * point(x0, t[2]);
      const Vector3d gap = point(x0, p) - q0;
      const double d0 = gap.norm();
      if (d0 < 1e-12) continue;  // touching at the start: no separating direction
      changed |= repel({p, t[0], t[1], t[2]}, {1.0, -w[0], -w[1], -w[2]}, gap / d0, d0, v, h, inverse_mass);
    }
    for (const auto& [e, g] : pairs.edge_edge) {
      const auto& a = edges_[static_cast<size_t>(e)];
      const auto& b = edges_[static_cast<size_t>(g)];
      const auto [s, t] =
          closest_segment_params(point(x0, a[0]), point(x0, a[1]), point(x0, b[0]), point(x0, b[1]));
      const Vector3d gap = ((1 - s) * point(x0, a[0]) + s * point(x0, a[1])) -
                           ((1 - t) * point(x0, b[0]) + t * point(x0, b[1]));
      const double d0 = gap.norm();
      if (d0 < 1e-12) continue;
      changed |= repel({a[0], a[1], b[0], b[1]}, {1 - s, s, -(1 - t), -t}, gap / d0, d0, v, h, inverse_mass);
    }
    if (!changed) break;
  }
}

}  // namespace phasecast::precompute
