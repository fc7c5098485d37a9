// phasecast-inspect: validate a scene package and print what it holds.

#include "phasecast/core/package.h"
#include "phasecast/core/package_summary.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  CLI::App app{
      "Validate a Phasecast scene package (HDF5) and print its scene, counts, ranks, "
      "reduction errors and the sizes a thin client downloads. Exits 0 on a valid "
      "package and 1 with a one-line reason otherwise."};
  std::string path;
  bool json = false;
  int rank = 0;
  app.add_option("package", path, "scene package (.h5)")->required();
  app.add_flag("--json", json, "print one JSON object instead of text");
  app.add_option("--rank", rank, "report the displacement error at this rank (default: r_u)")
      ->check(CLI::PositiveNumber);
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-inspect"))
    return *status;

  try {
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
