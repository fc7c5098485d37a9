#pragma once
// Volume meshing of a closed triangle surface with TetGen (constrained
// Delaunay, quality refinement), for the solid bodies (the toy).

#include "phasecast/precompute/simulation/obj_mesh.h"

#include <Eigen/Core>

namespace phasecast::precompute {

struct TetMesh {
  Eigen::MatrixX3d vertices;  // V x 3
  Eigen::MatrixX4i tets;      // T x 4, positively oriented (det[x1-x0, x2-x0, x3-x0] > 0)
  Eigen::MatrixX3i boundary;  // boundary triangles, outward facing
};

// Tetrahedralizes `surface` with tets no larger than `max_volume` and a
// radius-edge ratio bound `quality` (TetGen -pq<quality>a<max_volume>).
// Throws std::runtime_error when TetGen rejects the surface (open, self-intersecting).
TetMesh tetrahedralize(const ObjMesh& surface, double max_volume, double quality);

}  // namespace phasecast::precompute
