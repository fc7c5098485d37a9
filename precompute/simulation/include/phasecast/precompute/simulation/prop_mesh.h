#pragma once
// A rigid mesh that rides on the support: drawn and seen by the transfer
// (§4), never simulated. A black-box simulator's drawn objects arrive as
// these (Blender's `drawn`, docs/simulator.md); the built-in simulator's
// props are boxes (scene.h, PropLook).

#include <Eigen/Core>

#include <string>

namespace phasecast::precompute {

struct PropMesh {
  std::string name;
  Eigen::MatrixX3d positions;  // support frame at rest, one point per distinct corner normal (hard edges)
  Eigen::MatrixX3d normals;    // unit, per point
  Eigen::MatrixX3i triangles;  // counter-clockwise seen from outside
  Eigen::Vector3d albedo = Eigen::Vector3d::Constant(0.8);
};

}  // namespace phasecast::precompute
