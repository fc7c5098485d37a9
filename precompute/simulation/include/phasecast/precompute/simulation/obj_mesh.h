#pragma once
// Wavefront OBJ reading (tinyobjloader) and writing: vertices ("v") and faces ("f",
// polygons fan-triangulated, "a/b/c" and negative indices accepted). Enough
// for scene meshes, exported frames and imported orbits; anything else in a
// file (normals, texture coordinates, groups) is skipped.

#include <Eigen/Core>

#include <filesystem>
#include <stdexcept>

namespace phasecast::precompute {

class ObjError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ObjMesh {
  Eigen::MatrixX3d vertices;   // V x 3
  Eigen::MatrixX3i triangles;  // F x 3, 0-based
};

// Throws ObjError naming the file and line for unreadable files, malformed
// numbers, out-of-range indices and files tinyobjloader cannot parse.
ObjMesh read_obj(const std::filesystem::path& path);

// Writes atomically enough for viewers (one ofstream, checked at close).
// `lines` (E x 2, optional) become OBJ line elements ("l a b"): rods, stems.
void write_obj(const std::filesystem::path& path, const Eigen::MatrixX3d& vertices,
               const Eigen::MatrixX3i& triangles, const Eigen::MatrixX2i& lines = Eigen::MatrixX2i(0, 2));

}  // namespace phasecast::precompute
