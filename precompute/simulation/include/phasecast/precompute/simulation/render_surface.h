#pragma once
// The deformable surface a scene shows: the simulated vertices and surface of
// every body without a render mesh, then each body's render mesh (scene file
// `render`, docs/scenes.md), all as points embedded in the simulated vertices.
// A package's deformable scene points are these, then the back sides of the
// sheets among them; validation compares served and simulated motion on them.

#include "phasecast/precompute/simulation/embedding.h"
#include "phasecast/precompute/simulation/scene.h"

#include <cstdint>
#include <vector>

namespace phasecast::precompute {

struct RenderSurface {
  // P x V: point p at sum_i W_pi x_i. First the vertices of bodies without a
  // render mesh (ascending, each a row with one weight 1), then the render
  // meshes in body order. Without render meshes this is the identity.
  VertexEmbedding weights;
  Eigen::MatrixXi triangles;        // F x 3 over the P points
  std::vector<int> body;            // P: the body each point shows (a welded vertex: the last)
  std::vector<std::uint8_t> solid;  // P: moved by a vertex of a tetrahedron (a solid's boundary)

  Eigen::Index points() const { return weights.rows(); }
};

RenderSurface render_surface(const Scene& scene);

}  // namespace phasecast::precompute
