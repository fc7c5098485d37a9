// phasecast-precompute init: a commented starting scene from a template.

#include "commands.h"
#include "phasecast/precompute/simulation/scene.h"
#include "phasecast_scene_templates.h"

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>

namespace phasecast::precompute::tools {
namespace {

struct InitOptions {
  std::string name;
  std::string output;
  bool force = false;
};

const SceneTemplate& find_template(const std::string& name) {
  std::string known;
  for (const auto& t : kSceneTemplates) {
    if (name == t.name) return t;
    known += (known.empty() ? "" : ", ") + std::string(t.name);
  }
  throw std::invalid_argument(fmt::format("--template '{}' is unknown (expected one of {})", name, known));
}

std::string filled(std::string text, const std::string& key, const std::string& value) {
  for (auto at = text.find(key); at != std::string::npos; at = text.find(key, at + value.size()))
    text.replace(at, key.size(), value);
  return text;
}

void refuse_existing(const std::filesystem::path& path, bool force) {
  if (std::filesystem::exists(path) && !force)
    throw std::invalid_argument(
        fmt::format("{} exists (expected a new file, or --force to replace it)", path.string()));
}

void write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  out.close();
  if (!out) throw std::runtime_error(fmt::format("cannot write {}", path.string()));
}

void run_init(const InitOptions& o) {
  const SceneTemplate& t = find_template(o.name);
  const std::filesystem::path path(o.output);
  if (path.extension() != ".toml")
    throw std::invalid_argument(fmt::format("{}: expected a scene file name ending in .toml", o.output));
  const std::string stem = path.stem().string();
  if (stem.empty() ||
      stem.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") !=
          std::string::npos)
    throw std::invalid_argument(fmt::format(
        "{}: the file name is the scene's name (expected letters, digits, '_' and '-' before .toml)",
        o.output));
  const std::string mesh = stem + "_block.obj";
  std::string scene = filled(filled(filled(t.scene, "@NAME@", stem), "@FILE@", o.output), "@MESH@", mesh);
  const auto mesh_path = path.parent_path() / mesh;
  refuse_existing(path, o.force);
  if (*t.mesh) {
    refuse_existing(mesh_path, o.force);
    write_file(mesh_path, t.mesh);
  }
  write_file(path, scene);
  const Scene loaded = load_scene_file(path);  // a template that does not load is a bug here, not the user's
  fmt::print(
      "wrote {} ({}: {} vertices, palette {}){}\n", o.output, t.summary, loaded.model.vertices(),
      [&] {
        std::string names;
        for (const auto& e : loaded.palette) names += (names.empty() ? "" : ", ") + e.name;
        return names;
      }(),
      *t.mesh ? fmt::format(" and {}", mesh_path.string()) : "");
  fmt::print("next: phasecast-precompute simulate {} --schedule \"{}\" -o try.h5\n", o.output,
             loaded.standard_schedule);
  fmt::print(
      "      phasecast-render --simulation try.h5 --out sim/ && scripts/contact-sheet sim/ -o sim.png\n");
  fmt::print("      phasecast-precompute check {}\n", o.output);
}

}  // namespace

void add_init_command(CLI::App& app) {
  auto o = std::make_shared<InitOptions>();
  std::string names;
  for (const auto& t : kSceneTemplates) names += fmt::format("\n  {}: {}", t.name, t.summary);
  CLI::App* cmd = app.add_subcommand(
      "init",
      "Write a commented starting scene that simulates as written and carries a [validation] "
      "schedule and a [view]. Templates:" +
          names);
  cmd->add_option("--template", o->name, "door-cloth, hanging-banner, pushed-plant or jolted-solid")
      ->required();
  cmd->add_option("scene", o->output, "scene file to write (.toml); its name is the scene's name")
      ->required();
  cmd->add_flag("--force", o->force, "replace existing files");
  cmd->callback([o] { run_init(*o); });
}

}  // namespace phasecast::precompute::tools
