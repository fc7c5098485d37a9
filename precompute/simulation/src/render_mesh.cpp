#include "render_mesh.h"

#include "phasecast/precompute/simulation/obj_mesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>
#include <utility>
#include <vector>

namespace phasecast::precompute::detail {
namespace {

// Each level has four times the triangles: 5 levels make 1024.
constexpr int kMaxSubdivide = 5;

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

}  // namespace

RenderMesh read_render_mesh(Fields render, const std::filesystem::path& dir, const SimulatedBody& body) {
  const bool subdivide = render.has("subdivide"), obj = render.has("obj");
  if (subdivide == obj) {
    render.fail(obj ? "obj" : "subdivide",
                "either subdivide = n (Loop subdivision of the simulated surface) or obj = \"fine.obj\" (a "
                "surface inside a tetgen body)");
  }
  RenderMesh r = subdivide ? subdivided(render, body) : embedded_obj(render, dir, body);
  render.finish();
  return r;
}

}  // namespace phasecast::precompute::detail
