#pragma once
// A black-box simulator, as the paper's Maya and ABAQUS (§3): headless Blender
// steps a .blend's own simulation (its cloth, soft bodies, collisions and
// solver settings) while the palette's kinematics move the .blend's support
// object. One Blender process per simulator; docs/simulator.md, "Blender".

#include "phasecast/precompute/simulation/prop_mesh.h"
#include "phasecast/precompute/simulation/simulator.h"
#include "phasecast/precompute/simulation/support_motion.h"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace phasecast::precompute {

// A scene's [simulator] section with kind = "blender".
struct BlenderSettings {
  std::filesystem::path blend;          // absolute
  std::vector<std::string> deformable;  // objects whose evaluated vertices are the scene's points
  std::string support;                  // the object the palette's kinematics move
  std::vector<std::string> drawn;       // rigid objects moving with the support: drawn, seen by the transfer
  double timeout = 120;                 // s Blender may take for one answer before the run fails
};

// What the .blend holds at its first frame, in Phasecast's Y-up world.
struct BlenderDescription {
  struct Body {
    std::string name;
    int first = 0, count = 0;                                 // its vertices
    int first_triangle = 0, triangles = 0;                    // its rows of `triangles`
    Eigen::Vector3d colour = Eigen::Vector3d::Constant(0.8);  // the base colour of its first material
  };
  Eigen::VectorXd rest;              // 3V, the deformable objects' evaluated vertices in order
  Eigen::MatrixXi triangles;         // F x 3
  std::vector<std::uint8_t> pinned;  // V: in a cloth's pin group or a soft body's goal group
  std::vector<Body> bodies;
  std::vector<PropMesh> drawn;  // evaluated meshes (modifiers applied), base colour as albedo
  bool self_collision = false;
  double self_distance = 0;  // m, the largest of the cloths' self-collision distances
};

// Blender's Z-up world in Phasecast's Y-up one, as glTF maps them: (x, y, z) -> (x, z, -y).
Eigen::Matrix3d blender_to_phasecast();

// Runs Blender once on the .blend; SimulationError naming the .blend (and, for
// an unknown object, the objects it has) when it cannot.
BlenderDescription describe_blender_scene(const BlenderSettings& settings, double frame_dt);

// `rest` is the description's: the state a new process starts in.
std::unique_ptr<Simulator> make_blender_simulator(const BlenderSettings& settings, double frame_dt,
                                                  const SupportSettings& support,
                                                  const Eigen::VectorXd& rest);

}  // namespace phasecast::precompute
