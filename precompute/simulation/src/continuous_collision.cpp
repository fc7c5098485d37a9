#include "phasecast/precompute/simulation/continuous_collision.h"

#include "phasecast/precompute/simulation/self_collision.h"

#include "box_hash.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

namespace phasecast::precompute {
namespace {

using Eigen::Vector3d;
using Points = std::array<Vector3d, 4>;

// A pair closer than this at a coplanar time touches: far above rounding of
// metre-scale coordinates, far below any thickness a scene uses.
constexpr double kTouch = 1e-6;

Vector3d point(const Eigen::VectorXd& x, int i) {
  return x.segment<3>(3 * i);
}

// Coefficients of f(t) = ((q1 - q0) x (q2 - q0)) . (q3 - q0) for points moving
// linearly from s to e, lowest order first: f = 0 when the four are coplanar.
std::array<double, 4> coplanarity_cubic(const Points& s, const Points& e) {
  const Vector3d u0 = s[1] - s[0], w0 = s[2] - s[0], r0 = s[3] - s[0];
  const Vector3d du = (e[1] - e[0]) - u0, dw = (e[2] - e[0]) - w0, dr = (e[3] - e[0]) - r0;
  const Vector3d n0 = u0.cross(w0), n1 = u0.cross(dw) + du.cross(w0), n2 = du.cross(dw);
  return {n0.dot(r0), n0.dot(dr) + n1.dot(r0), n1.dot(dr) + n2.dot(r0), n2.dot(dr)};
}

// Times in [0, 1] worth a proximity test, ascending: the cubic's roots (by
// bisection on its monotone pieces), its interior extrema (near-tangency) and
// the end of the step.
std::vector<double> coplanar_times(const std::array<double, 4>& c) {
  const auto f = [&c](double t) { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; };
  const double scale = std::abs(c[0]) + std::abs(c[1]) + std::abs(c[2]) + std::abs(c[3]);
  if (scale < 1e-300) return {0.0, 0.25, 0.5, 0.75, 1.0};  // coplanar throughout: sample the step
  std::vector<double> knots{0.0, 1.0};
  const double a = 3 * c[3], b = 2 * c[2], k = c[1];  // f'(t) = a t^2 + b t + k
  if (std::abs(a) > 1e-18 * scale) {
    const double disc = b * b - 4 * a * k;
    if (disc >= 0) {
      const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
      knots.push_back(q / a);
      if (q != 0) knots.push_back(k / q);
    }
  } else if (b != 0) {
    knots.push_back(-k / b);
  }
  knots.erase(std::remove_if(knots.begin(), knots.end(), [](double t) { return !(t >= 0 && t <= 1); }),
              knots.end());
  std::sort(knots.begin(), knots.end());
  std::vector<double> times(knots.begin() + 1, knots.end() - 1);  // the extrema
  for (size_t i = 0; i + 1 < knots.size(); ++i) {
    double lo = knots[i], hi = knots[i + 1], flo = f(lo);
    const double fhi = f(hi);
    if (flo == 0) times.push_back(lo);
    if (flo * fhi >= 0) continue;
    for (int it = 0; it < 60 && hi - lo > 1e-13; ++it) {
      const double mid = 0.5 * (lo + hi), fm = f(mid);
      if ((fm < 0) == (flo < 0)) {
        lo = mid, flo = fm;
      } else {
        hi = mid;
      }
    }
    times.push_back(hi);
  }
  // The end is always tested: obstacle clipping puts two layers pressed onto a
  // padded face exactly coplanar there, and rounding of f(1) can hide that root.
  times.push_back(1.0);
  std::sort(times.begin(), times.end());
  return times;
}

Points at(const Points& s, const Points& e, double t) {
  Points p;
  for (size_t i = 0; i < 4; ++i) p[i] = s[i] + t * (e[i] - s[i]);
  return p;
}

// Vertex-triangle points are ordered (p, a, b, c); the cubic wants (a, b, c, p).
Points triangle_first(const Points& p) {
  return {p[1], p[2], p[3], p[0]};
}

double vertex_triangle_distance(const Points& p) {
  const Vector3d w = closest_barycentric(p[0], p[1], p[2], p[3]);
  return (p[0] - (w[0] * p[1] + w[1] * p[2] + w[2] * p[3])).norm();
}

double edge_edge_distance(const Points& p) {
  const auto [s, t] = closest_segment_params(p[0], p[1], p[2], p[3]);
  return ((p[0] + s * (p[1] - p[0])) - (p[2] + t * (p[3] - p[2]))).norm();
}

template <class Distance>
std::optional<double> first_contact(const Points& cubic_start, const Points& cubic_end, const Points& start,
                                    const Points& end, double tolerance, Distance distance) {
  for (double t : coplanar_times(coplanarity_cubic(cubic_start, cubic_end))) {
    if (distance(at(start, end, t)) <= tolerance) return t;
  }
  return std::nullopt;
}

// Weights and unit normal of a vertex-triangle contact at positions p (at the
// contact time); the normal points from the triangle towards the vertex as it
// was at the start, so an impulse along it undoes the crossing.
ContinuousCollision::Collision vertex_triangle_collision(const std::array<int, 4>& v, const Points& start,
                                                         const Points& p) {
  const Vector3d w = closest_barycentric(p[0], p[1], p[2], p[3]);
  Vector3d n = (p[2] - p[1]).cross(p[3] - p[1]);
  if (n.norm() < 1e-14) n = start[0] - (w[0] * start[1] + w[1] * start[2] + w[2] * start[3]);
  if (n.dot(start[0] - start[1]) < 0) n = -n;
  return {v, {1.0, -w[0], -w[1], -w[2]}, n.norm() > 0 ? Vector3d(n.normalized()) : Vector3d::Zero()};
}

ContinuousCollision::Collision edge_edge_collision(const std::array<int, 4>& v, const Points& start,
                                                   const Points& p) {
  const auto [s, t] = closest_segment_params(p[0], p[1], p[2], p[3]);
  const Vector3d gap0 = (start[0] + s * (start[1] - start[0])) - (start[2] + t * (start[3] - start[2]));
  Vector3d n = (p[1] - p[0]).cross(p[3] - p[2]);
  if (n.norm() < 1e-14 * (p[1] - p[0]).norm() * (p[3] - p[2]).norm()) n = gap0;
  if (n.dot(gap0) < 0) n = -n;
  return {v, {1 - s, s, -(1 - t), -t}, n.norm() > 0 ? Vector3d(n.normalized()) : Vector3d::Zero()};
}

Eigen::AlignedBox3d swept(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1,
                          std::initializer_list<int> vs) {
  Eigen::AlignedBox3d box;
  for (int v : vs) box.extend(point(x0, v)).extend(point(x1, v));
  box.min().array() -= kTouch;
  box.max().array() += kTouch;
  return box;
}

Points corners(const Eigen::VectorXd& x, const std::array<int, 4>& v) {
  return {point(x, v[0]), point(x, v[1]), point(x, v[2]), point(x, v[3])};
}

// Union-find over vertices with a sticky "hold still" mark per zone.
class ImpactZones {
 public:
  explicit ImpactZones(int n) : parent_(static_cast<size_t>(n)), hold_(static_cast<size_t>(n), 0) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  int root(int i) {
    while (parent_[static_cast<size_t>(i)] != i)
      i = parent_[static_cast<size_t>(i)] = parent_[static_cast<size_t>(parent_[static_cast<size_t>(i)])];
    return i;
  }
  void unite(int a, int b) {
    a = root(a), b = root(b);
    if (a == b) return;
    if (b < a) std::swap(a, b);
    parent_[static_cast<size_t>(b)] = a;
    hold_[static_cast<size_t>(a)] |= hold_[static_cast<size_t>(b)];
  }
  void hold(int i) { hold_[static_cast<size_t>(root(i))] = 1; }
  bool held(int i) { return hold_[static_cast<size_t>(root(i))] != 0; }

 private:
  std::vector<int> parent_;
  std::vector<std::uint8_t> hold_;
};

}  // namespace

std::optional<double> vertex_triangle_contact(const Points& start, const Points& end, double tolerance) {
  return first_contact(triangle_first(start), triangle_first(end), start, end, tolerance,
                       vertex_triangle_distance);
}

std::optional<double> edge_edge_contact(const Points& start, const Points& end, double tolerance) {
  return first_contact(start, end, start, end, tolerance, edge_edge_distance);
}

ContinuousCollision::ContinuousCollision(Eigen::MatrixXi triangles, double separation, int passes,
                                         bool incremental)
    : triangles_(std::move(triangles)),
      edges_(surface_edges(triangles_)),
      separation_(separation),
      passes_(passes),
      incremental_(incremental) {
  vertex_count_ = triangles_.size() ? triangles_.maxCoeff() + 1 : 0;
}

namespace {

// The swept boxes of every surface vertex, triangle and edge over a step.
struct SweptPrimitives {
  std::vector<Eigen::AlignedBox3d> vertices, triangles, edges;

  SweptPrimitives(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, int vertex_count,
                  const Eigen::MatrixXi& tris, const std::vector<std::array<int, 2>>& edge_list) {
    for (int p = 0; p < vertex_count; ++p) vertices.push_back(swept(x0, x1, {p}));
    for (Eigen::Index f = 0; f < tris.rows(); ++f)
      triangles.push_back(swept(x0, x1, {tris(f, 0), tris(f, 1), tris(f, 2)}));
    for (const auto& e : edge_list) edges.push_back(swept(x0, x1, {e[0], e[1]}));
  }
};

bool before(const ContinuousCollision::Collision& a, const ContinuousCollision::Collision& b) {
  return std::tie(a.edge_edge, a.pair) < std::tie(b.edge_edge, b.pair);
}

}  // namespace

// Vertex p against triangle f, and edge i against edge g (g > i), as detect() tests them.
std::optional<ContinuousCollision::Collision> ContinuousCollision::test_vertex_triangle(
    const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, int p, int f) const {
  const std::array<int, 4> v = {p, triangles_(f, 0), triangles_(f, 1), triangles_(f, 2)};
  if (v[1] == p || v[2] == p || v[3] == p) return std::nullopt;
  const Points s = corners(x0, v), e = corners(x1, v);
  const auto t = vertex_triangle_contact(s, e, kTouch);
  if (!t) return std::nullopt;
  Collision c = vertex_triangle_collision(v, s, at(s, e, *t));
  c.pair = {p, f};
  return c;
}

std::optional<ContinuousCollision::Collision> ContinuousCollision::test_edge_edge(const Eigen::VectorXd& x0,
                                                                                  const Eigen::VectorXd& x1,
                                                                                  int i, int g) const {
  const auto& a = edges_[static_cast<size_t>(i)];
  const auto& b = edges_[static_cast<size_t>(g)];
  if (a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1]) return std::nullopt;
  const std::array<int, 4> v = {a[0], a[1], b[0], b[1]};
  const Points s = corners(x0, v), e = corners(x1, v);
  const auto t = edge_edge_contact(s, e, kTouch);
  if (!t) return std::nullopt;
  Collision c = edge_edge_collision(v, s, at(s, e, *t));
  c.edge_edge = true;
  c.pair = {i, g};
  return c;
}

std::vector<ContinuousCollision::Collision> ContinuousCollision::detect(const Eigen::VectorXd& x0,
                                                                        const Eigen::VectorXd& x1) const {
  std::vector<Collision> out;
  const SweptPrimitives box(x0, x1, vertex_count_, triangles_, edges_);
  const BoxHash tri_hash(box.triangles), edge_hash(box.edges);
  std::vector<int> near;
  for (int p = 0; p < vertex_count_; ++p) {
    tri_hash.overlapping(box.vertices[static_cast<size_t>(p)], near);
    for (int f : near)
      if (auto c = test_vertex_triangle(x0, x1, p, f)) out.push_back(*c);
  }
  for (int i = 0; i < static_cast<int>(edges_.size()); ++i) {
    edge_hash.overlapping(box.edges[static_cast<size_t>(i)], near);
    for (int g : near)
      if (g > i)
        if (auto c = test_edge_edge(x0, x1, i, g)) out.push_back(*c);
  }
  return out;
}

std::vector<ContinuousCollision::Collision> ContinuousCollision::detect_moved(
    const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, const std::vector<Collision>& previous,
    const std::vector<std::uint8_t>& moved) const {
  const auto has_moved = [&moved](std::initializer_list<int> vs) {
    return std::any_of(vs.begin(), vs.end(), [&moved](int v) { return moved[static_cast<size_t>(v)] != 0; });
  };
  std::vector<Collision> out;
  for (const auto& c : previous)  // unmoved pairs keep their result
    if (!has_moved({c.vertex[0], c.vertex[1], c.vertex[2], c.vertex[3]})) out.push_back(c);
  // Every overlapping pair with a moved vertex, found from its moved side.
  const SweptPrimitives box(x0, x1, vertex_count_, triangles_, edges_);
  const BoxHash tri_hash(box.triangles), edge_hash(box.edges);
  std::vector<std::array<int, 2>> vertex_triangle, edge_edge;
  std::vector<int> near;
  for (int p = 0; p < vertex_count_; ++p) {
    if (!moved[static_cast<size_t>(p)]) continue;
    tri_hash.overlapping(box.vertices[static_cast<size_t>(p)], near);
    for (int f : near) vertex_triangle.push_back({p, f});
  }
  // Still vertices against moved triangles: a hash of the moved triangles
  // only, queried by every still vertex's small box (a hash of the vertices,
  // sized to their boxes, would make a triangle's query visit far too many cells).
  std::vector<int> moved_triangles;
  std::vector<Eigen::AlignedBox3d> moved_boxes;
  for (int f = 0; f < static_cast<int>(triangles_.rows()); ++f) {
    if (!has_moved({triangles_(f, 0), triangles_(f, 1), triangles_(f, 2)})) continue;
    moved_triangles.push_back(f);
    moved_boxes.push_back(box.triangles[static_cast<size_t>(f)]);
  }
  if (!moved_triangles.empty()) {
    const BoxHash moved_hash(moved_boxes);
    for (int p = 0; p < vertex_count_; ++p) {
      if (moved[static_cast<size_t>(p)]) continue;
      moved_hash.overlapping(box.vertices[static_cast<size_t>(p)], near);
      for (int k : near) vertex_triangle.push_back({p, moved_triangles[static_cast<size_t>(k)]});
    }
  }
  for (int i = 0; i < static_cast<int>(edges_.size()); ++i) {
    if (!has_moved({edges_[static_cast<size_t>(i)][0], edges_[static_cast<size_t>(i)][1]})) continue;
    edge_hash.overlapping(box.edges[static_cast<size_t>(i)], near);
    for (int g : near)
      if (g != i) edge_edge.push_back({std::min(i, g), std::max(i, g)});
  }
  std::sort(edge_edge.begin(), edge_edge.end());
  edge_edge.erase(std::unique(edge_edge.begin(), edge_edge.end()), edge_edge.end());
  for (const auto& [p, f] : vertex_triangle)
    if (auto c = test_vertex_triangle(x0, x1, p, f)) out.push_back(*c);
  for (const auto& [i, g] : edge_edge)
    if (auto c = test_edge_edge(x0, x1, i, g)) out.push_back(*c);
  std::sort(out.begin(), out.end(), before);  // detect()'s order: impulses apply in it
  return out;
}

namespace {

// Inelastic impulse that leaves the pair separating along n at separation / h.
void apply_impulse(const ContinuousCollision::Collision& c, Eigen::VectorXd& v, double target,
                   const Eigen::VectorXd& inverse_mass) {
  double vn = 0, inv = 0;
  for (size_t k = 0; k < 4; ++k) {
    vn += c.weight[k] * point(v, c.vertex[k]).dot(c.normal);
    inv += c.weight[k] * c.weight[k] * inverse_mass[c.vertex[k]];
  }
  if (vn >= target || inv <= 0 || c.normal.isZero(0)) return;
  const double impulse = (target - vn) / inv;
  for (size_t k = 0; k < 4; ++k)
    v.segment<3>(3 * c.vertex[k]) += impulse * c.weight[k] * inverse_mass[c.vertex[k]] * c.normal;
}

// Each zone moves with its mass-weighted mean velocity, or is held still.
void move_zones(ImpactZones& zones, const std::vector<std::uint8_t>& in_zone, Eigen::VectorXd& v,
                const Eigen::VectorXd& inverse_mass) {
  const auto n = static_cast<int>(in_zone.size());
  std::vector<Vector3d> momentum(static_cast<size_t>(n), Vector3d::Zero());
  std::vector<double> mass(static_cast<size_t>(n), 0.0);
  for (int i = 0; i < n; ++i) {
    if (!in_zone[static_cast<size_t>(i)]) continue;
    const auto r = static_cast<size_t>(zones.root(i));
    if (inverse_mass[i] == 0) zones.hold(i);
    if (inverse_mass[i] > 0) momentum[r] += point(v, i) / inverse_mass[i], mass[r] += 1 / inverse_mass[i];
  }
  for (int i = 0; i < n; ++i) {
    if (!in_zone[static_cast<size_t>(i)] || inverse_mass[i] == 0) continue;
    const auto r = static_cast<size_t>(zones.root(i));
    v.segment<3>(3 * i) = zones.held(i) || mass[r] == 0 ? Vector3d::Zero() : Vector3d(momentum[r] / mass[r]);
  }
}

// Whether every free surface vertex (the first `vertices`) ends where it may.
bool ends_admissibly(int vertices, const Eigen::VectorXd& x0, const Eigen::VectorXd& v, double h,
                     const Eigen::VectorXd& inverse_mass, const EndAdmissible& admissible) {
  for (int i = 0; i < vertices; ++i) {
    if (inverse_mass[i] > 0 && !admissible(i, point(x0, i) + h * point(v, i))) return false;
  }
  return true;
}

}  // namespace

CcdReport ContinuousCollision::resolve(const Eigen::VectorXd& x0, Eigen::VectorXd& v, double h,
                                       const Eigen::VectorXd& inverse_mass,
                                       const EndAdmissible& admissible) const {
  CcdReport report;
  if (triangles_.rows() == 0) return report;
  const double target = separation_ / h;
  // Each detection after the first tests again only the pairs of vertices whose velocity changed.
  std::vector<Collision> found;
  Eigen::VectorXd v_detected;
  const auto detect_step = [&]() -> const std::vector<Collision>& {
    const Eigen::VectorXd x1 = x0 + h * v;
    if (!incremental_ || v_detected.size() == 0) {
      found = detect(x0, x1);
    } else {
      std::vector<std::uint8_t> moved(static_cast<size_t>(vertex_count_), 0);
      for (int i = 0; i < vertex_count_; ++i)
        moved[static_cast<size_t>(i)] = point(v, i) != point(v_detected, i);
      found = detect_moved(x0, x1, found, moved);
    }
    v_detected = v;
    return found;
  };
  bool clean = false;  // the last detection found nothing: the fail-safe needs no second one
  for (int pass = 0; pass < passes_ && !clean; ++pass) {
    detect_step();
    clean = found.empty();
    report.collisions += static_cast<int>(found.size());
    for (const auto& c : found) apply_impulse(c, v, target, inverse_mass);
  }
  if (clean && ends_admissibly(vertex_count_, x0, v, h, inverse_mass, admissible)) return report;
  // Fail-safe: merge whatever still collides (or ends inadmissibly) into zones.
  ImpactZones zones(vertex_count_);
  std::vector<std::uint8_t> in_zone(static_cast<size_t>(vertex_count_), 0);
  for (int round = 0; round <= vertex_count_; ++round) {
    const Eigen::VectorXd x1 = x0 + h * v;
    bool changed = false;
    for (const auto& c : detect_step()) {
      const int r = zones.root(c.vertex[0]);
      bool one_zone = in_zone[static_cast<size_t>(c.vertex[0])] != 0;
      for (int k : c.vertex) one_zone &= in_zone[static_cast<size_t>(k)] && zones.root(k) == r;
      if (one_zone) continue;  // a zone moves rigidly: its own pairs cannot cross
      for (int k : c.vertex) zones.unite(c.vertex[0], k), in_zone[static_cast<size_t>(k)] = 1;
      changed = true;
    }
    for (int i = 0; i < vertex_count_; ++i) {
      if (inverse_mass[i] == 0 || admissible(i, point(x1, i))) continue;
      if (in_zone[static_cast<size_t>(i)] && zones.held(i)) continue;
      in_zone[static_cast<size_t>(i)] = 1, zones.hold(i), changed = true;
    }
    if (!changed) break;
    move_zones(zones, in_zone, v, inverse_mass);
  }
  for (int i = 0; i < vertex_count_; ++i) {
    if (!in_zone[static_cast<size_t>(i)]) continue;
    ++report.zone_vertices;
    if (zones.held(i)) ++report.frozen_vertices;
  }
  return report;
}

}  // namespace phasecast::precompute
