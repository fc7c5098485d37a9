#pragma once
// Scene files (TOML, docs/scenes.md): bodies with their meshes, energies and
// materials, rigid obstacles, the moving support, simulation settings and the
// impulse palette (§3.3) with the support kinematics each entry implies.

#include "phasecast/core/package.h"
#include "phasecast/precompute/simulation/blender_simulator.h"
#include "phasecast/precompute/simulation/deformable_model.h"
#include "phasecast/precompute/simulation/embedding.h"
#include "phasecast/precompute/simulation/simulator.h"
#include "phasecast/precompute/simulation/support_motion.h"

#include <Eigen/Core>

#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::precompute {

// Every invalid scene file: one line naming the file and the field.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One named palette entry: alpha_I and alpha_F (support velocities, see support_motion.h).
struct PaletteEntry {
  std::string name;
  Eigen::Vector3d alpha_impulse = Eigen::Vector3d::Zero();
  Eigen::Vector3d alpha_forcing = Eigen::Vector3d::Zero();
  // Sampling rules (docs/sampling.md; checked by make_palette_rules in palette_rules.h).
  std::vector<std::string> after;  // entries ("rest" = from rest) this one may follow; empty: any
  double t_min = 0.1;              // s: shortest IRF the sampler draws
  double t_max = 1.0;              // s: longest IRF the sampler draws
  std::string on_end = "rest";     // "rest", "hold" or the name of a follow-up entry
  std::string group;               // entries of one group count together for max_in_a_row ("": own name)
  int max_in_a_row = 0;            // at most this many IRFs of the group in a row (0: unlimited)
};

// The vertices a body owns in the assembled model (welded vertices included).
inline const Eigen::Vector3d kDefaultAlbedo{0.8, 0.8, 0.8};

struct BodyInfo {
  std::string name;
  std::vector<int> vertices;
  int first_surface_triangle = 0;
  int surface_triangles = 0;
  Eigen::Vector3d albedo = kDefaultAlbedo;  // diffuse rho per RGB channel (§4.1), for the transfer
  std::optional<RenderMesh> render;         // shown instead of the simulated surface (scene file `render`)
};

inline constexpr int kMaxPropCells = 256;  // cells along one edge of a tessellated prop

// How a rigid obstacle looks to the appearance stage; the simulator sees only its box.
struct PropLook {
  Eigen::Vector3d albedo = kDefaultAlbedo;
  double cell = 0;    // m: the faces are tessellated into squares of about this edge (0: one quad a face)
  bool drawn = true;  // false: collision only, no scene points (geometry no camera sees, whose
                      // transfer would spend U_a's directions on invisible variation)
};

// [appearance]: the scene's defaults for the appearance stage (§4); the
// command line overrides each. 0 means "the tool's default".
struct AppearanceDefaults {
  int clusters = 0;      // N_a
  double eps_a = 0;      // r_a = number of sigma_i >= eps_a sigma_1
  int held_out = 0;      // state nodes whose true transfer measures the served appearance
  int rays = 0;          // transfer directions: more where ray noise outweighs the variation
  int paper_rank_a = 0;  // the paper's r_a for this scene (Table 1): inspect prints the error there
};

// [demo]: what `scripts/demo` plays on this scene: the example Lua script
// phasecast-console runs and the sampling seed of its small package.
struct DemoDefaults {
  std::filesystem::path script;  // absolute, resolved against the scene file's folder (may not exist)
  int seed = 1;
};

// [view]: how the clients show the scene where their own flags are absent
// (phasecast-render, the browser page, scripts/demo, the glTF camera); the
// package stores it (docs/package-format.md, root attributes).
struct ViewSettings {
  std::optional<Eigen::Vector3d> eye, target;  // the camera: both or neither
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();
  double fov_y_deg = 40;
  bool floor = true;                   // floor = "none": no floor
  std::optional<double> floor_height;  // floor = y; absent: under the rest mesh's lowest point
  std::string light;                   // SH light probe; empty: the client's default
  std::optional<double> exposure;
};

struct Scene {
  std::string name;
  std::filesystem::path source;
  SimulationSettings simulation;
  SupportSettings support;
  DeformableModel model;
  std::vector<BodyInfo> bodies;
  std::vector<PropLook> props;        // one per model.obstacles entry
  std::vector<PropMesh> prop_meshes;  // drawn after the box props (Blender's drawn objects)
  AppearanceDefaults appearance;
  std::vector<PaletteEntry> palette;
  // [validation] schedule: the interaction `phasecast-precompute validate`
  // plays by default ("open 0.8; stop 1.5; ..."); parsed where it is used.
  std::string standard_schedule;
  std::optional<DemoDefaults> demo;
  std::optional<ViewSettings> view;
  // [simulator] kind = "blender": Blender steps the .blend (the model then
  // holds only what Blender described: points, triangles; its drawn objects
  // are prop_meshes).
  std::optional<BlenderSettings> blender;

  // Index of the palette entry `name`; throws SceneError listing the known names.
  int palette_index(const std::string& entry) const;
};

// Parses and validates a scene file and assembles its DeformableModel.
Scene load_scene_file(const std::filesystem::path& path);

// The rigid-support motion palette entry `entry` implies, in the package's terms.
core::SupportKinematics entry_kinematics(const Scene& scene, int entry);

// The scene's implicit simulator.
std::unique_ptr<Simulator> make_simulator(const Scene& scene);

}  // namespace phasecast::precompute
