#pragma once
// Small meshes with known transfer: icosphere, flat-shaded cube, square
// planes, an open box. All tiny so the tests stay fast.

#include "phasecast/precompute/appearance/transfer_file.h"

namespace phasecast::testing {

// Icosahedron subdivided `levels` times, projected onto the unit sphere;
// normals are the exact sphere normals (the positions).
precompute::TransferMesh icosphere(int levels);

// Unit cube [-0.5, 0.5]^3 with 4 points per face carrying the face normal, so
// every point's hemisphere is exactly above its face.
precompute::TransferMesh flat_cube();

// Square [-h, h]^2 at height z, an n x n grid of quads, facing +z (or -z).
precompute::TransferMesh square(float half, float z, int n, bool facing_up);

// Appends b's points and triangles to a.
precompute::TransferMesh merge(const precompute::TransferMesh& a, const precompute::TransferMesh& b);

// Open box: floor and four inner walls of the unit cube, facing inward, no lid.
precompute::TransferMesh open_box(int n);

// Exit radiance of each point and channel under a constant white sky L = 1:
// T[p, 16 c + 0] * L_0 with L_0 = 4 pi Y_0.
Eigen::MatrixXd furnace(const MatrixXfR& transfer);

}  // namespace phasecast::testing
