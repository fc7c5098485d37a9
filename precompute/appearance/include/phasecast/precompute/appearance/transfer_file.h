#pragma once
// The standalone transfer tool's inputs and outputs: a static mesh from an OBJ
// file, and the transfer file (HDF5) of docs/transfer.md.

#include "phasecast/core/eigen_types.h"
#include "phasecast/precompute/appearance/transfer.h"

#include <filesystem>

namespace phasecast::precompute {

// Scene points with their normals and the triangles over them.
struct TransferMesh {
  MatrixXfR positions;  // S x 3
  MatrixXuR triangles;  // F x 3
  MatrixXfR normals;    // S x 3 unit
};

// Reads an OBJ file (polygons triangulated; groups merged). Scene points are
// the OBJ's vertices, normals are angle-weighted vertex normals of its faces.
// Throws std::runtime_error naming the file for a missing or malformed file,
// one without faces, or non-finite coordinates.
TransferMesh load_obj_mesh(const std::filesystem::path& path);

// Both sides of a thin surface as scene points: appends a copy of every point
// with the negated normal and every triangle with reversed winding over the
// copies. Back faces get their own transfer.
TransferMesh make_double_sided(const TransferMesh& mesh);

// Contents of a transfer file.
struct TransferFile {
  MatrixXfR positions;      // /positions  S x 3
  MatrixXfR normals;        // /normals    S x 3
  MatrixXfR transfer;       // /transfer   S x 3 x 16 (stored 3-D; here S x 48)
  TransferOptions options;  // attributes mode, rays, bounces, albedo
};

// Writes atomically (temporary file renamed over `path`).
void write_transfer_file(const TransferFile& file, const std::filesystem::path& path);
// Throws std::runtime_error naming the file and dataset for anything else.
TransferFile read_transfer_file(const std::filesystem::path& path);

}  // namespace phasecast::precompute
