#pragma once
// Render meshes driven by the simulation mesh, as the paper's dinosaur
// ("displacements were interpolated onto a finer surface"): a sparse linear
// embedding W puts render point p at sum_i W_pi x_i over the simulated
// vertices x, plus a fixed offset d_p for a rod tube's rings (PointOffset).
// Every row sums to 1, so W reproduces affine motions exactly (translations
// only, where a point has an offset), the render rest is W X + d, and a render
// point moves by W (x - X). The orbit store and the SVD stay on the simulated
// vertices; a package's rows are W x-bar + d and W U_u
// (docs/package-format.md). A simulated vertex shown as it is is the row with
// one weight 1.

#include "phasecast/core/eigen_types.h"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace phasecast::precompute {

// P x V weights of P render points over V simulated vertices; row-major, so a
// point's weights are contiguous. Rows of static points are empty.
using VertexEmbedding = Eigen::SparseMatrix<double, Eigen::RowMajor>;

// Render points set off from where their weights put them by a fixed rest
// offset d_p: a ring point of a rod's tube (`render = { tube = k }`) is its
// axis vertex plus d_p. An embedding must stay linear in the vertices (the
// package's rows are W U_u), so the offset translates with the point and
// does not turn with the rod: a tube's ring stays parallel to its rest plane
// (for a thin rod the bend only shears it). Only nonzero offsets, ascending p.
struct PointOffset {
  Eigen::Index point = 0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
};
using PointOffsets = std::vector<PointOffset>;

// Scene points over the simulated vertices: point p at sum_i W_pi x_i + d_p.
struct Embedding {
  VertexEmbedding weights;  // P x V
  PointOffsets offsets;
};

// A body's render mesh (scene file `render`): its points are W X + d, W over the
// scene's simulated vertices (columns: the vertices existing when the body was read).
struct RenderMesh {
  VertexEmbedding weights;    // P x V
  Eigen::MatrixXi triangles;  // F x 3 over the P points, counter-clockwise like the simulated surface
  PointOffsets offsets;       // a tube's rings around its rod's vertices
  bool tube = false;          // drawn around a rod: closed, and outside the simulation's self-contact
};

// The same weights applied to each coordinate: rows 3p..3p+2 of the result
// are sum_i W_pi rows 3i..3i+2 of `rows` (3V x c): positions (c = 1), x-bar,
// U_u. Rows of points with no weights are 0. Accumulates in double.
// Throws std::invalid_argument when `rows` does not have 3V rows.
MatrixXfR embed_rows(const VertexEmbedding& W, const Eigen::Ref<const MatrixXfR>& rows);

// Positions of the points: embed_rows(W, x), each column a set of vertex
// positions, plus each point's offset (positions, not displacements: U_u
// rows take embed_rows alone).
MatrixXfR embed_positions(const VertexEmbedding& W, const PointOffsets& d,
                          const Eigen::Ref<const MatrixXfR>& x);
inline MatrixXfR embed_positions(const Embedding& e, const Eigen::Ref<const MatrixXfR>& x) {
  return embed_positions(e.weights, e.offsets, x);
}

// Whether point p of W moves with the simulated vertices (its row has weights).
bool embeds(const VertexEmbedding& W, Eigen::Index p);

// Loop subdivision (Loop 1987), `levels` times, of a triangle mesh over
// `vertices` points: the subdivided mesh's points are W times the original
// ones. Old points first, then one point per edge (edges sorted), per level.
//   edge points     3/8, 3/8 on the edge, 1/8, 1/8 opposite; boundary edges 1/2, 1/2
//   vertex points   (1 - k beta) v + beta * sum of its k neighbours, Loop's beta =
//                   (5/8 - (3/8 + cos(2 pi / k) / 4)^2) / k (1/16 at k = 6);
//                   boundary vertices 3/4 v + 1/8 each boundary neighbour; a vertex
//                   on more than two boundary edges (two fans touching) stays put
// Every triangle becomes four with the same orientation.
struct Subdivision {
  VertexEmbedding weights;    // subdivided points x `vertices`
  Eigen::MatrixXi triangles;  // 4^levels F x 3
};
Subdivision loop_subdivision(const Eigen::MatrixXi& triangles, int vertices, int levels);

// Barycentric coordinates of `points` in a tetrahedral mesh: each point gets
// the four weights of the tet containing it, or, when it lies outside every
// tet, those of the tet behind the nearest boundary triangle, extrapolated
// (still exact for affine motions). Points more than `max_outside` metres
// outside are refused.
//   @param[in] points    P x 3
//   @param[in] rest      3V vertex rest positions
//   @param[in] tets      T x 4 vertex indices, non-degenerate
//   @param[in] boundary  B x 3 boundary triangles (faces of the tets)
// Throws std::invalid_argument naming the first point too far outside.
VertexEmbedding tet_embedding(const Eigen::MatrixX3d& points, const Eigen::VectorXd& rest,
                              const Eigen::MatrixX4i& tets, const Eigen::MatrixXi& boundary,
                              double max_outside);

}  // namespace phasecast::precompute
