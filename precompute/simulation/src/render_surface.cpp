#include "phasecast/precompute/simulation/render_surface.h"

#include <algorithm>

namespace phasecast::precompute {
namespace {

// The points of bodies shown as simulated: a vertex is one when a body
// without a render mesh owns it (the stem's vertex a rendered leaf is welded to).
void add_simulated_points(const Scene& scene, RenderSurface& s, std::vector<Eigen::Triplet<double>>& w) {
  const auto V = static_cast<size_t>(scene.model.vertices());
  std::vector<int> shown_by(V, -1), point_of(V, -1);
  for (size_t b = 0; b < scene.bodies.size(); ++b)
    if (!scene.bodies[b].render)
      for (int v : scene.bodies[b].vertices) shown_by[static_cast<size_t>(v)] = static_cast<int>(b);
  for (size_t v = 0; v < V; ++v) {
    if (shown_by[v] < 0) continue;
    point_of[v] = static_cast<int>(s.body.size());
    w.emplace_back(point_of[v], static_cast<int>(v), 1.0);
    s.body.push_back(shown_by[v]);
  }
  std::vector<int> triangles;
  for (const auto& body : scene.bodies) {
    if (body.render) continue;
    for (int t = body.first_surface_triangle; t < body.first_surface_triangle + body.surface_triangles; ++t)
      for (int k = 0; k < 3; ++k)
        triangles.push_back(point_of[static_cast<size_t>(scene.model.surface(t, k))]);
  }
  s.triangles = Eigen::Map<const Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>(
      triangles.data(), static_cast<Eigen::Index>(triangles.size() / 3), 3);
}

void add_render_meshes(const Scene& scene, RenderSurface& s, std::vector<Eigen::Triplet<double>>& w) {
  for (size_t b = 0; b < scene.bodies.size(); ++b) {
    const auto& render = scene.bodies[b].render;
    if (!render) continue;
    const auto first = static_cast<int>(s.body.size());
    for (Eigen::Index p = 0; p < render->weights.rows(); ++p) {
      for (VertexEmbedding::InnerIterator it(render->weights, p); it; ++it)
        w.emplace_back(first + static_cast<int>(p), static_cast<int>(it.col()), it.value());
      s.body.push_back(static_cast<int>(b));
    }
    for (const auto& d : render->offsets) s.offsets.push_back({first + d.point, d.offset});
    s.tube.resize(s.body.size(), 0);
    std::fill(s.tube.begin() + first, s.tube.end(), render->tube ? 1 : 0);
    const Eigen::Index F = s.triangles.rows();
    s.triangles.conservativeResize(F + render->triangles.rows(), 3);
    s.triangles.bottomRows(render->triangles.rows()) = render->triangles.array() + first;
  }
}

// A point moved by a tet vertex lies on a solid's boundary: one side only.
std::vector<std::uint8_t> solid_points(const DeformableModel& model, const VertexEmbedding& W) {
  std::vector<std::uint8_t> in_tet(static_cast<size_t>(model.vertices()), 0), solid;
  for (const auto& t : model.tets)
    for (int v : t.v) in_tet[static_cast<size_t>(v)] = 1;
  for (Eigen::Index p = 0; p < W.rows(); ++p) {
    std::uint8_t any = 0;
    for (VertexEmbedding::InnerIterator it(W, p); it; ++it) any |= in_tet[static_cast<size_t>(it.col())];
    solid.push_back(any);
  }
  return solid;
}

}  // namespace

RenderSurface render_surface(const Scene& scene) {
  RenderSurface s;
  std::vector<Eigen::Triplet<double>> w;
  add_simulated_points(scene, s, w);
  add_render_meshes(scene, s, w);
  s.weights.resize(static_cast<Eigen::Index>(s.body.size()), scene.model.vertices());
  s.weights.setFromTriplets(w.begin(), w.end());
  s.tube.resize(s.body.size(), 0);
  s.solid = solid_points(scene.model, s.weights);
  for (size_t p = 0; p < s.solid.size(); ++p) s.solid[p] |= s.tube[p];
  return s;
}

Eigen::MatrixXi contact_triangles(const RenderSurface& surface) {
  std::vector<Eigen::Index> kept;
  for (Eigen::Index t = 0; t < surface.triangles.rows(); ++t)
    if (!surface.tube[static_cast<size_t>(surface.triangles(t, 0))]) kept.push_back(t);
  Eigen::MatrixXi out(static_cast<Eigen::Index>(kept.size()), 3);
  for (size_t i = 0; i < kept.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = surface.triangles.row(kept[i]);
  return out;
}

}  // namespace phasecast::precompute
