// phasecast-precompute check: scene health, told at once (docs/check.md).

#include "commands.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/pipeline/scene_check.h"
#include "phasecast/precompute/sampling/palette_rules.h"

#include <fmt/format.h>

#include <memory>
#include <stdexcept>
#include <string>

namespace phasecast::precompute::tools {
namespace {

struct CheckOptions {
  std::string scene;
  std::string package;
  SceneCheckOptions check;
};

void run_check(const CheckOptions& o) {
  const Scene scene = load_scene_file(o.scene);
  make_palette_rules(scene);  // the palette's rules first: a broken rule is the first thing to fix
  std::optional<core::ScenePackage> package;
  if (!o.package.empty()) {
    package = core::read_package(o.package);
    std::vector<std::string> names;
    for (const auto& e : scene.palette) names.push_back(e.name);
    if (package->attributes.scene != scene.name || package->palette.names != names) {
      throw std::invalid_argument(fmt::format(
          "--package {} is of scene '{}' with {} palette entries; {} is scene '{}' with {} (expected "
          "a package of this scene, its palette names in the same order)",
          o.package, package->attributes.scene, package->palette.names.size(), o.scene, scene.name,
          names.size()));
    }
  }
  const SceneCheck c = check_and_report(scene, package ? &*package : nullptr, o.check);
  if (const int n = c.problems(); n > 0) {
    throw std::runtime_error(
        fmt::format("{}: {} problem{} found (above, each with its fix)", o.scene, n, n > 1 ? "s" : ""));
  }
}

}  // namespace

SceneCheck check_and_report(const Scene& scene, const core::ScenePackage* package,
                            const SceneCheckOptions& options) {
  core::ProgressBar bar("check");
  std::string last;
  const SceneCheck c =
      check_scene(scene, package, options, [&](const std::string& stage, int done, int total) {
        if (stage != last) bar.restart(last = stage);
        bar.update(done, total);
      });
  bar.finish();
  for (const auto& line : c.report(options)) fmt::print("{}\n", line);
  return c;
}

void add_check_command(CLI::App& app) {
  auto o = std::make_shared<CheckOptions>();
  CLI::App* cmd = app.add_subcommand(
      "check",
      "Scene health: whether the settled rest is a rest, whether each moving palette entry followed by a "
      "quiet "
      "one returns to it (a neutral mode such as a flag turning about its pole is named), and with "
      "--package, "
      "IRFs per entry and a short fidelity estimate. Exit status 1 when a problem is found.");
  cmd->add_option("scene", o->scene, "scene file (.toml)")->required();
  cmd->add_option("--package", o->package, "a package of the scene: IRFs per entry and a fidelity estimate");
  cmd->add_option("--stop-seconds", o->check.stop_seconds,
                  "quiet time after each entry (default: 3 s, or the quiet entry's t_max if longer)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--schedules", o->check.fidelity_schedules,
                  "random schedules of the fidelity estimate (with --package; 0: none)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->callback([o] {
    Ranks::world().require_one_process("check");
    run_check(*o);
  });
}

}  // namespace phasecast::precompute::tools
