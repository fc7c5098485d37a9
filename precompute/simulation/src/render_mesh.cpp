#include "render_mesh.h"

#include "phasecast/precompute/simulation/obj_mesh.h"

#include <fmt/format.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

namespace phasecast::precompute::detail {
namespace {

// Each level has four times the triangles: 5 levels make 1024.
constexpr int kMaxSubdivide = 5;
// A tube's sides: a triangle at least; beyond 32 a thin stem looks no rounder.
constexpr int kMinTubeSides = 3, kMaxTubeSides = 32;
constexpr double kPi = 3.14159265358979323846;

// How far outside the tets a render vertex may lie, in mean boundary edge
// lengths: a finer surface of the same shape strays about a fraction of an
// edge from the coarse one; farther, extrapolated weights amplify the tets'
// non-affine motion (and usually mean the OBJ is misplaced).
constexpr double kMaxOutsideEdges = 0.5;

double mean_edge(const Eigen::VectorXd& rest, const Eigen::MatrixXi& triangles) {
  double sum = 0;
  for (Eigen::Index t = 0; t < triangles.rows(); ++t)
    for (int k = 0; k < 3; ++k)
      sum += (rest.segment<3>(3 * triangles(t, k)) - rest.segment<3>(3 * triangles(t, (k + 1) % 3))).norm();
  return triangles.rows() ? sum / static_cast<double>(3 * triangles.rows()) : 0;
}

// The body's surface over its own vertices: their model indices, ascending,
// and the triangles renumbered to positions in that list.
std::pair<std::vector<int>, Eigen::MatrixXi> own_vertices(const Eigen::MatrixXi& surface) {
  std::vector<int> vertices(surface.data(), surface.data() + surface.size());
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  Eigen::MatrixXi local = surface;
  for (Eigen::Index i = 0; i < local.size(); ++i)
    local(i) =
        static_cast<int>(std::lower_bound(vertices.begin(), vertices.end(), local(i)) - vertices.begin());
  return {vertices, local};
}

// Loop subdivision of the body's own surface, its weights over the model's vertices.
RenderMesh subdivided(Fields& render, const SimulatedBody& body) {
  const int levels = render.positive_integer("subdivide", 0);
  if (levels > kMaxSubdivide)
    render.fail("subdivide",
                fmt::format("a subdivision level in 1..{} (each level has 4x the triangles)", kMaxSubdivide));
  if (body.surface.rows() == 0)
    render.fail("subdivide", "a body with a triangle surface (grid, obj or tetgen) to subdivide");
  const auto [vertices, local] = own_vertices(body.surface);
  const Subdivision s = loop_subdivision(local, static_cast<int>(vertices.size()), levels);
  std::vector<Eigen::Triplet<double>> w;
  for (Eigen::Index p = 0; p < s.weights.rows(); ++p)
    for (VertexEmbedding::InnerIterator it(s.weights, p); it; ++it)
      w.emplace_back(static_cast<int>(p), vertices[static_cast<size_t>(it.col())], it.value());
  RenderMesh r;
  r.weights.resize(s.weights.rows(), body.rest.size() / 3);
  r.weights.setFromTriplets(w.begin(), w.end());
  r.triangles = s.triangles;
  return r;
}

// A finer surface inside a solid, moved by the tets containing its vertices.
RenderMesh embedded_obj(Fields& render, const std::filesystem::path& dir, const SimulatedBody& body) {
  if (body.tets.rows() == 0)
    render.fail("obj", "a tetgen body (a render OBJ moves with the tets around it; sheets use subdivide)");
  const auto fail = [&](const std::string& what) {
    throw SceneError(fmt::format("{}: field '{}': {}", render.file(), render.path("obj"), what));
  };
  ObjMesh mesh;
  try {
    mesh = read_obj(dir / render.string("obj"));
  } catch (const ObjError& e) {
    fail(e.what());
  }
  const Eigen::MatrixX3d points = (mesh.vertices * body.scale).rowwise() + body.translate.transpose();
  RenderMesh r;
  try {
    r.weights = tet_embedding(points, body.rest, body.tets, body.surface,
                              kMaxOutsideEdges * mean_edge(body.rest, body.surface));
  } catch (const std::invalid_argument& e) {
    fail(fmt::format("{}; mesh the tets from a surface that encloses the render mesh", e.what()));
  }
  r.triangles = mesh.triangles;
  return r;
}

// A rod's tube: the first ring's frame, carried from ring to ring by the
// least rotation that turns one tangent into the next (parallel transport: no
// twist between rings, and no flip at a sharp bend).
struct RingFrame {
  Eigen::Vector3d tangent, e1, e2;
};

// Some unit vector across `t`.
Eigen::Vector3d across(const Eigen::Vector3d& t) {
  return t.cross(std::abs(t.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).normalized();
}

// The ring's normal at vertex i: the bisector of its two edges' directions
// (an end vertex: its one edge), so a ring halves the angle of a bend.
Eigen::Vector3d ring_tangent(const std::vector<Eigen::Vector3d>& axis, size_t i) {
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  if (i > 0) t += (axis[i] - axis[i - 1]).normalized();
  if (i + 1 < axis.size()) t += (axis[i + 1] - axis[i]).normalized();
  // A rod that folds straight back on itself: the incoming edge's direction.
  return t.norm() > 1e-9 ? t.normalized() : (axis[i] - axis[i - 1]).normalized();
}

std::vector<RingFrame> ring_frames(const std::vector<Eigen::Vector3d>& axis) {
  std::vector<RingFrame> frames;
  for (size_t i = 0; i < axis.size(); ++i) {
    const Eigen::Vector3d t = ring_tangent(axis, i);
    Eigen::Vector3d e1 = across(t);
    if (!frames.empty()) {
      const Eigen::Vector3d carried =
          Eigen::Quaterniond::FromTwoVectors(frames.back().tangent, t) * frames.back().e1;
      e1 = (carried - carried.dot(t) * t).normalized();
    }
    frames.push_back({t, e1, t.cross(e1)});
  }
  return frames;
}

// The polyline's vertices in order; a rod that branches or is not one chain is refused.
std::vector<int> polyline_vertices(Fields& render, const SimulatedBody& body) {
  if (body.segments.empty() || body.radius <= 0)
    render.fail("tube", "a rod body (a polyline with 'rod' energy and a radius) to draw as a tube");
  std::vector<int> chain{body.segments.front()[0]};
  for (const auto& s : body.segments) {
    if (s[0] != chain.back()) render.fail("tube", "a rod that is one polyline, its segments in order");
    chain.push_back(s[1]);
  }
  return chain;
}

// Triangles of a tube of n rings of k points (ring i: k i .. k i + k - 1),
// then the two cap centres k n and k n + 1, counter-clockwise seen from
// outside (e1, e2 and the tangent are right-handed).
Eigen::MatrixXi tube_triangles(int n, int k) {
  const int start_cap = n * k, end_cap = start_cap + 1, last = k * (n - 1);
  std::vector<Eigen::Vector3i> triangles;
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j < k; ++j) {
      const int a = k * i + j, b = k * i + (j + 1) % k, c = a + k, d = b + k;
      triangles.emplace_back(a, b, d);
      triangles.emplace_back(a, d, c);
    }
  for (int j = 0; j < k; ++j) {
    triangles.emplace_back(start_cap, (j + 1) % k, j);
    triangles.emplace_back(end_cap, last + j, last + (j + 1) % k);
  }
  Eigen::MatrixXi out(static_cast<Eigen::Index>(triangles.size()), 3);
  for (size_t t = 0; t < triangles.size(); ++t) out.row(static_cast<Eigen::Index>(t)) = triangles[t];
  return out;
}

// `tube = k`: a ring of k points around each rod vertex at the rod's radius,
// each moved by its vertex alone (weight 1 plus a rest offset), closed by a
// cap at each end (a centre point on the end vertex and a fan).
RenderMesh tube(Fields& render, const SimulatedBody& body) {
  const int k = render.positive_integer("tube", 0);
  if (k < kMinTubeSides || k > kMaxTubeSides)
    render.fail("tube", fmt::format("the sides of the tube's rings, {}..{}", kMinTubeSides, kMaxTubeSides));
  const std::vector<int> chain = polyline_vertices(render, body);
  std::vector<Eigen::Vector3d> axis;
  for (int v : chain) axis.push_back(body.rest.segment<3>(3 * v));
  const auto frames = ring_frames(axis);
  const auto n = static_cast<int>(chain.size());
  RenderMesh r;
  r.tube = true;
  std::vector<Eigen::Triplet<double>> w;
  for (int i = 0; i < n; ++i) {
    const auto& f = frames[static_cast<size_t>(i)];
    for (int j = 0; j < k; ++j) {
      const double angle = 2 * kPi * j / k;
      w.emplace_back(k * i + j, chain[static_cast<size_t>(i)], 1.0);
      r.offsets.push_back({k * i + j, body.radius * (std::cos(angle) * f.e1 + std::sin(angle) * f.e2)});
    }
  }
  w.emplace_back(n * k, chain.front(), 1.0);
  w.emplace_back(n * k + 1, chain.back(), 1.0);
  r.weights.resize(n * k + 2, body.rest.size() / 3);
  r.weights.setFromTriplets(w.begin(), w.end());
  r.triangles = tube_triangles(n, k);
  return r;
}

}  // namespace

RenderMesh read_render_mesh(Fields render, const std::filesystem::path& dir, const SimulatedBody& body) {
  const bool subdivide = render.has("subdivide"), obj = render.has("obj"), tubed = render.has("tube");
  if (subdivide + obj + tubed != 1) {
    render.fail(obj     ? "obj"
                : tubed ? "tube"
                        : "subdivide",
                "one of subdivide = n (Loop subdivision of the simulated surface), obj = \"fine.obj\" (a "
                "surface inside a tetgen body) or tube = k (a rod drawn as a tube of k sides)");
  }
  RenderMesh r = subdivide ? subdivided(render, body)
                 : obj     ? embedded_obj(render, dir, body)
                           : tube(render, body);
  render.finish();
  return r;
}

}  // namespace phasecast::precompute::detail
