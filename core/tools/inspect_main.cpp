// phasecast-inspect: validate a scene package and print what it holds; an
// orbit store (simulate, sample, import) is recognised and summarised.

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"
#include "phasecast/core/package_summary.h"
#include "phasecast/precompute/sampling/orbit_store.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <exception>

namespace {

// An orbit store, read without its frames: what made it and what it holds.
// False when `path` is not one (then it is read as a package).
bool summarize_orbit_store(const std::string& path, bool json) {
  try {
    if (phasecast::core::h5::File::open_read(path).read_attribute_string("format") != "phasecast-orbits")
      return false;
  } catch (const std::exception&) {
    return false;
  }
  const phasecast::precompute::OrbitStoreReader store(path);
  const auto& h = store.header();
  const auto& irfs = store.irfs();
  std::vector<int> per_entry(h.palette_names.size(), 0);
  long frames = 0;
  for (std::size_t i = 0; i < irfs.size(); ++i) {
    ++per_entry.at(static_cast<std::size_t>(irfs.palette[i]));
    frames += irfs.length[i];
  }
  nlohmann::json j{{"kind", "orbit store"},
                   {"scene", h.scene},
                   {"source", h.source},
                   {"scene_file", h.scene_file},
                   {"dt", h.dt},
                   {"vertices", h.vertices()},
                   {"triangles", h.triangles.rows()},
                   {"frames", frames},
                   {"seconds", frames * h.dt},
                   {"irfs", irfs.size()}};
  for (std::size_t e = 0; e < per_entry.size(); ++e) j["irfs_per_entry"][h.palette_names[e]] = per_entry[e];
  if (json) {
    fmt::print("{}\n", j.dump(2));
    return true;
  }
  fmt::print("{}: an orbit store (not a package: phasecast-precompute reduce or run makes one from it)\n",
             path);
  fmt::print("scene '{}' from {}{}\n", h.scene, h.source,
             h.scene_file.empty() ? "" : ", scene file " + h.scene_file);
  fmt::print("{} vertices, {} triangles; {} frames ({:.2f} s at dt {} s) in {} IRFs\n", h.vertices(),
             h.triangles.rows(), frames, frames * h.dt, h.dt, irfs.size());
  for (std::size_t e = 0; e < per_entry.size(); ++e)
    fmt::print("  {:<12} {} IRFs\n", h.palette_names[e], per_entry[e]);
  fmt::print("see it: phasecast-render --simulation {}\n", path);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Validate a Phasecast scene package (HDF5) and print its scene, counts, ranks, "
      "reduction errors and the sizes a thin client downloads; an orbit store (simulate, sample, "
      "import) is summarised instead. Exits 0 on a valid package or store and 1 with a one-line "
      "reason otherwise."};
  std::string path;
  bool json = false;
  int rank = 0;
  app.add_option("package", path, "scene package or orbit store (.h5)")->required();
  app.add_flag("--json", json, "print one JSON object instead of text");
  app.add_option("--rank", rank, "report the displacement error at this rank (default: r_u)")
      ->check(CLI::PositiveNumber);
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-inspect"))
    return *status;

  try {
    if (summarize_orbit_store(path, json)) return 0;
    const auto package = phasecast::core::read_package(path);
    const auto summary = phasecast::core::summarize(package, path, rank);
    if (json) {
      fmt::print("{}\n", phasecast::core::to_json(summary).dump(2));
    } else {
      fmt::print("{}", phasecast::core::to_text(summary));
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-inspect: {}\n", e.what());
    return 1;
  }
  return 0;
}
