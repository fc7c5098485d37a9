// phasecast-precompute simulate: run a scene through a schedule of palette entries.

#include "commands.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/pipeline/contact_report.h"
#include "phasecast/precompute/sampling/obj_frames.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "tet_report.h"

#include <fmt/format.h>

#include <cmath>
#include <memory>
#include <string>

namespace phasecast::precompute::tools {
namespace {

struct SimulateOptions {
  std::string scene;
  std::string schedule;
  std::string output;
  std::string obj_dir;
};

void run_simulate(const SimulateOptions& o) {
  using namespace phasecast::precompute;
  const Scene scene = load_scene_file(o.scene);
  make_palette_rules(scene);  // the palette's rules are checked as run checks them, before any simulation
  const auto schedule = parse_schedule(o.schedule, scene);
  fmt::print(stderr, "{}: {} vertices, {} surface triangles, {} tetrahedra, {} palette entries, {} IRFs\n",
             scene.name, scene.model.vertices(), scene.model.surface.rows(), scene.model.tets.size(),
             scene.palette.size(), schedule.size());
  phasecast::core::ProgressBar bar("simulate");
  const OrbitStore store =
      simulate_schedule(scene, schedule, [&](int done, int total) { bar.update(done, total); });
  bar.finish();
  write_orbit_store(store, o.output);
  fmt::print("wrote {} ({} frames, {} IRFs)\n", o.output, store.frames(), store.irf_start.size());
  if (scene.model.self_collision) {
    const double close = close_distance(scene);
    fmt::print("{}\n", contact_line(summarize_contact(store.positions, scene.model.surface, close,
                                                      scene.model.thickness),
                                    close));
  }
  if (!scene.model.tets.empty()) {
    fmt::print("{}\n", tet_line(summarize_tets(scene.model, store.positions),
                                static_cast<int>(scene.model.tets.size())));
  }
  if (!o.obj_dir.empty()) {
    phasecast::core::ProgressBar obj_bar("obj frames");
    const int n = write_obj_frames(store, scene.model.obstacles, scene.prop_meshes, o.obj_dir,
                                   [&](int done, int total) { obj_bar.update(done, total); });
    obj_bar.finish();
    fmt::print("wrote {} OBJ frames to {}\n", n, o.obj_dir);
  }
}

}  // namespace

void add_simulate_command(CLI::App& app) {
  auto options = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Simulate a scene under a schedule of palette entries and write the orbit store (HDF5).");
  cmd->add_option("scene", options->scene, "scene file (.toml)")->required();
  cmd->add_option("--schedule", options->schedule,
                  "palette entries with durations, e.g. \"open 1.5; stop 2\"")
      ->required();
  cmd->add_option("-o,--output", options->output, "orbit store to write (.h5)")->required();
  cmd->add_option("--obj-dir", options->obj_dir, "also write one world-space OBJ per frame into this folder");
  cmd->callback([options] {
    Ranks::world().require_one_process("simulate");
    run_simulate(*options);
  });
}

}  // namespace phasecast::precompute::tools
