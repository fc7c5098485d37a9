#pragma once
// Geometry of triangle meshes shared by the package builder and the transfer
// stage: one definition of vertex normals and of the back side of thin sheets.

#include "phasecast/core/eigen_types.h"

#include <vector>

namespace phasecast::core {

// Angle-weighted vertex normals (Thuermer & Wuethrich 1998): independent of
// how polygons were split into triangles, so a cube corner gets the diagonal.
// Points in no triangle, or only in degenerate ones, get (0, 0, 1).
MatrixXfR vertex_normals(const MatrixXfR& positions, const MatrixXuR& triangles);

// The back side of a thin sheet, so each side of it shows its own transfer:
// appends a copy of each point in `back` with the flipped normal, and a copy,
// with reversed winding, of every triangle whose three corners are in `back`.
// Returns the index of each point's copy (-1 for points not in `back`).
std::vector<std::int64_t> add_back_side(MatrixXfR& positions, MatrixXfR& normals, MatrixXuR& triangles,
                                        const std::vector<int>& back);

}  // namespace phasecast::core
