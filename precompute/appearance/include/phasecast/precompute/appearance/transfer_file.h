#pragma once
// The standalone transfer tool's inputs and outputs: a static mesh from an OBJ
// file, and the transfer file (HDF5) of docs/transfer.md; and the appearance
// stage's transfers file (`--save-transfers`), which keeps every true transfer
// the stage computed for analysis outside the tools.

#include "phasecast/core/eigen_types.h"
#include "phasecast/precompute/appearance/transfer.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

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

// What each transfer of the appearance stage was computed for.
enum class TransferRole : std::uint8_t {
  representative = 0,  // a cluster's representative: U_a and M-bar are made from these (§4.2)
  picking = 1,         // a held-out node of the half that picks the model
  reported = 2,        // a held-out node of the half that reports its error (never chooses)
};

// Every true transfer the appearance stage computed, with what is needed to
// use them without the package: the state node and role of each, the
// k-means labels, the scene points. The contents of docs/transfer.md's
// "transfers file" (format phasecast-stage-transfers).
struct StageTransfers {
  std::string scene;                     // the scene's name
  std::vector<std::int32_t> nodes;       // T state nodes (rows of the package's /portrait/q_u)
  std::vector<TransferRole> roles;       // T: representatives, then picking, then reported
  MatrixXfR fields;                      // T x 48S: transfer at each node (S x 3 x 16 per row)
  MatrixXfR q_u;                         // T x r_u: the nodes' reduced coordinates
  std::vector<std::int32_t> labels;      // N: k-means cluster of every state node
  MatrixXfR rest_positions;              // S x 3: the scene points at rest (support frame)
  std::vector<std::uint8_t> deformable;  // S: 1 = moved by U_u
  std::int32_t rays = 0, bounces = 0;    // how the transfers were sampled
};

// Writes atomically. Throws std::invalid_argument for inconsistent sizes and
// std::runtime_error naming the file when it cannot be written.
void write_stage_transfers(const StageTransfers& transfers, const std::filesystem::path& path);
// Throws std::runtime_error naming the file and dataset for anything else
// than what write_stage_transfers writes.
StageTransfers read_stage_transfers(const std::filesystem::path& path);

}  // namespace phasecast::precompute
