#include "phasecast/precompute/simulation/self_collision.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <unordered_map>
#include <utility>

namespace phasecast::precompute {
namespace {

using Eigen::Vector3d;

Vector3d point(const Eigen::VectorXd& x, int i) {
  return x.segment<3>(3 * i);
}

// Spatial hash of integer cells; key from the three cell coordinates.
std::int64_t cell_key(std::int64_t i, std::int64_t j, std::int64_t k) {
  return (i * 73856093) ^ (j * 19349663) ^ (k * 83492791);
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
  int count = 0;
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    const auto t = corners(f);
    const Eigen::AlignedBox3d bt = Eigen::AlignedBox3d(t[0]).extend(t[1]).extend(t[2]);
    for (Eigen::Index g = f + 1; g < tris.rows(); ++g) {
      bool shared = false;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) shared |= tris(f, a) == tris(g, b);
      if (shared) continue;
      const auto u = corners(g);
      const Eigen::AlignedBox3d bu = Eigen::AlignedBox3d(u[0]).extend(u[1]).extend(u[2]);
      if (bt.intersects(bu) && triangles_intersect(t, u)) ++count;
    }
  }
  return count;
}

SelfCollision::SelfCollision(Eigen::MatrixXi triangles, double thickness, int sweeps)
    : triangles_(std::move(triangles)), thickness_(thickness), sweeps_(sweeps) {
  vertex_count_ = triangles_.size() ? triangles_.maxCoeff() + 1 : 0;
  std::set<std::array<int, 2>> unique;
  for (Eigen::Index f = 0; f < triangles_.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = triangles_(f, k), b = triangles_(f, (k + 1) % 3);
      unique.insert({std::min(a, b), std::max(a, b)});
    }
  }
  edges_.assign(unique.begin(), unique.end());
}

namespace {

// Uniform grid hash over boxes; cell size is the mean box extent so each box touches few cells.
class BoxHash {
 public:
  explicit BoxHash(const std::vector<Eigen::AlignedBox3d>& boxes) : boxes_(boxes) {
    double extent = 1e-9;
    for (const auto& b : boxes) extent += b.sizes().maxCoeff() / static_cast<double>(boxes.size());
    cell_ = extent;
    for (size_t i = 0; i < boxes.size(); ++i) {
      visit(boxes[i], [&](std::int64_t key) { cells_[key].push_back(static_cast<int>(i)); });
    }
  }

  // Indices of boxes overlapping `query`, sorted and unique (deterministic).
  std::vector<int> overlapping(const Eigen::AlignedBox3d& query) const {
    std::vector<int> out;
    visit(query, [&](std::int64_t key) {
      const auto it = cells_.find(key);
      if (it == cells_.end()) return;
      for (int i : it->second) {
        if (boxes_[static_cast<size_t>(i)].intersects(query)) out.push_back(i);
      }
    });
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
  }

 private:
  template <class F>
  void visit(const Eigen::AlignedBox3d& b, F&& f) const {
    const auto index = [&](double c) { return static_cast<std::int64_t>(std::floor(c / cell_)); };
    for (auto i = index(b.min().x()); i <= index(b.max().x()); ++i)
      for (auto j = index(b.min().y()); j <= index(b.max().y()); ++j)
        for (auto k = index(b.min().z()); k <= index(b.max().z()); ++k) f(cell_key(i, j, k));
  }
  const std::vector<Eigen::AlignedBox3d>& boxes_;
  double cell_ = 1;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

Eigen::AlignedBox3d swept_box(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1,
                              std::initializer_list<int> vs, double pad) {
  Eigen::AlignedBox3d box;
  for (int v : vs) box.extend(point(x0, v)).extend(point(x1, v));
  box.min().array() -= pad;
  box.max().array() += pad;
  return box;
}

// Closest points of segments p0p1 and q0q1 as parameters (s, t) (Ericson 5.1.9).
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
  for (int v = 0; v < vertex_count_; ++v) {
    for (int f : tri_hash.overlapping(swept_box(x0, x1, {v}, 0.0))) {
      if (triangles_(f, 0) != v && triangles_(f, 1) != v && triangles_(f, 2) != v)
        pairs.vertex_triangle.push_back({v, f});
    }
  }
  for (size_t e = 0; e < edges_.size(); ++e) {
    for (int g : edge_hash.overlapping(edge_boxes[e])) {
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
// h stays at least `thickness`. Returns whether velocities changed.
bool SelfCollision::repel(const std::array<int, 4>& idx, const std::array<double, 4>& weight,
                          const Vector3d& n, double d0, Eigen::VectorXd& v, double h,
                          const Eigen::VectorXd& inverse_mass) const {
  double vn = 0, inv = 0;
  for (int k = 0; k < 4; ++k) {
    if (weight[static_cast<size_t>(k)] == 0) continue;
    vn += weight[static_cast<size_t>(k)] * point(v, idx[static_cast<size_t>(k)]).dot(n);
    inv += weight[static_cast<size_t>(k)] * weight[static_cast<size_t>(k)] *
           inverse_mass[idx[static_cast<size_t>(k)]];
  }
  const double target = std::max(0.0, thickness_ - d0) / h;
  if (d0 + h * vn >= thickness_ || vn >= target || inv <= 0) return false;
  const double impulse = (target - vn) / inv;
  for (int k = 0; k < 4; ++k) {
    const int i = idx[static_cast<size_t>(k)];
    v.segment<3>(3 * i) += impulse * weight[static_cast<size_t>(k)] * inverse_mass[i] * n;
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
