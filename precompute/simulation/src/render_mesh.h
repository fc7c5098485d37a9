#pragma once
// The `render` table of a scene file's body (docs/scenes.md): a finer mesh
// shown instead of the body's simulated surface, and its embedding in the
// simulated vertices. Private to the simulation section (scene.cpp reads it).

#include "phasecast/precompute/simulation/embedding.h"
#include "phasecast/precompute/simulation/scene_fields.h"

#include <Eigen/Core>

#include <array>
#include <filesystem>
#include <vector>

namespace phasecast::precompute::detail {

// What the reader needs of the body it embeds into.
struct SimulatedBody {
  const Eigen::VectorXd& rest;  // 3V rest positions of the model so far
  Eigen::MatrixXi surface;      // the body's surface triangles, model vertex indices
  Eigen::MatrixX4i tets;        // the body's tets, model vertex indices (solids)
  double scale = 1;             // placement of the body's tetgen OBJ, which a render OBJ shares
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();
  std::vector<std::array<int, 2>> segments;  // the body's rod segments in polyline order, model indices
  double radius = 0;                         // m: a rod's radius, the tube's
};

// `render = { subdivide = n }`, for a solid `render = { obj = "fine.obj" }`,
// for a rod `render = { tube = k }`.
// Throws SceneError naming the field.
RenderMesh read_render_mesh(Fields render, const std::filesystem::path& dir, const SimulatedBody& body);

}  // namespace phasecast::precompute::detail
