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
  // Positions: embed_positions(weights, offsets, x).
  VertexEmbedding weights;
  PointOffsets offsets;             // the rings of rods' tubes: p at W_p x + d_p
  Eigen::MatrixXi triangles;        // F x 3 over the P points
  std::vector<int> body;            // P: the body each point shows (a welded vertex: the last)
  std::vector<std::uint8_t> solid;  // P: on a closed surface (a solid's boundary or a tube): one side
  std::vector<std::uint8_t> tube;   // P: drawn around a rod, which self-contact does not see

  Eigen::Index points() const { return weights.rows(); }
  Embedding embedding() const { return {weights, offsets}; }
};

// The triangles self-contact keeps apart: all but the tubes'. A tube is
// drawn around a rod the contact sees as a line, so it crosses the leaf its
// petiole enters and the tubes of the rods welded to it by construction.
Eigen::MatrixXi contact_triangles(const RenderSurface& surface);

RenderSurface render_surface(const Scene& scene);

}  // namespace phasecast::precompute
