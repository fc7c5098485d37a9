#pragma once
// Scene files for the sampling tests: the shipped tiny cloth_door and variants
// of it written into a scratch folder.

#include "phasecast/precompute/simulation/scene.h"
#include "run_tool.h"
#include "source_tree.h"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace phasecast::testing {

inline std::filesystem::path tiny_scene_path() {
  return scenes_dir() / "tiny" / "cloth_door.toml";
}

// The tiny scene with `from` replaced by `to` (first occurrence), written to dir/name.
inline std::filesystem::path edited_tiny_scene(const std::filesystem::path& dir, const std::string& from,
                                               const std::string& to,
                                               const std::string& name = "scene.toml") {
  std::string text = read_file(tiny_scene_path());
  const auto at = text.find(from);
  if (at == std::string::npos)
    throw std::runtime_error("edited_tiny_scene: '" + from + "' not in the tiny scene");
  text.replace(at, from.size(), to);
  const auto path = dir / name;
  std::ofstream(path) << text;
  return path;
}

}  // namespace phasecast::testing
