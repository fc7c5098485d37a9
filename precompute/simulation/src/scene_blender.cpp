#include "scene_blender.h"

#include <fmt/format.h>

namespace phasecast::precompute::detail {
namespace {

constexpr const char* kBlendersOwn =
    "no value with [simulator] kind = \"blender\" (the .blend's settings apply)";

BlenderSettings read_simulator(Fields sim, const std::filesystem::path& folder) {
  BlenderSettings s;
  sim.string("kind");
  s.blend = folder / sim.string("blend");
  // make = ["maker.py", args...]: the Python that writes the .blend (scripts/demo runs it when missing).
  std::vector<std::string> make;
  if (sim.has("make")) make = sim.strings("make");
  if (!std::filesystem::exists(s.blend)) {
    std::string how = "a .blend made in Blender";
    if (!make.empty()) {
      how = fmt::format("blender -b --factory-startup --python {} -- {}", (folder / make[0]).string(),
                        s.blend.string());
      for (size_t i = 1; i < make.size(); ++i) how += " " + make[i];
    }
    throw SceneError(
        fmt::format("{}: field '{}': {} does not exist (expected an existing .blend file; make it "
                    "with: {})",
                    sim.file(), sim.path("blend"), s.blend.string(), how));
  }
  s.deformable = sim.strings("deformable");
  if (s.deformable.empty()) sim.fail("deformable", "a list of at least one object name");
  s.support = sim.string("support");
  if (sim.has("drawn")) s.drawn = sim.strings("drawn");
  s.timeout = sim.positive("timeout", s.timeout);
  sim.finish();
  return s;
}

void add_description(Scene& scene, const BlenderDescription& d) {
  DeformableModel& m = scene.model;
  m.rest = d.rest;
  m.mass = Eigen::VectorXd::Ones(d.rest.size() / 3);  // Blender's own masses move the points
  m.pinned = d.pinned;
  m.surface = d.triangles;
  m.self_collision = d.self_collision;
  if (d.self_distance > 0) m.thickness = d.self_distance;
  for (const auto& b : d.bodies) {
    BodyInfo info;
    info.name = b.name;
    for (int v = 0; v < b.count; ++v) info.vertices.push_back(b.first + v);
    info.first_surface_triangle = b.first_triangle;
    info.surface_triangles = b.triangles;
    info.albedo = b.colour;
    scene.bodies.push_back(std::move(info));
  }
  scene.prop_meshes = d.drawn;
}

}  // namespace

SimulationSettings read_blender_simulation(Fields sim, double default_settle) {
  SimulationSettings s;
  s.frame_dt = sim.positive("frame_dt");
  s.settle = sim.number("settle", default_settle);
  if (s.settle < 0) sim.fail("settle", "a number >= 0");
  for (const char* key : {"substeps", "newton_iterations", "newton_tolerance", "gravity", "mass_damping",
                          "stiffness_damping", "max_speed", "friction", "linear_solver", "integrator"})
    if (sim.has(key)) sim.fail(key, kBlendersOwn);
  sim.finish();
  return s;
}

void read_blender_model(Fields& top, Scene& scene) {
  for (const char* key : {"body", "obstacle", "contact", "brace"})
    if (top.has(key)) top.fail(key, kBlendersOwn);
  scene.blender = read_simulator(top.table("simulator"), scene.source.parent_path());
  try {
    add_description(scene, describe_blender_scene(*scene.blender, scene.simulation.frame_dt));
  } catch (const SimulationError& e) {
    throw SceneError(fmt::format("{}: [simulator]: {}", top.file(), e.what()));
  }
  if (scene.model.vertices() == 0) top.fail("simulator", "deformable objects with at least one vertex");
}

}  // namespace phasecast::precompute::detail
