// phasecast-make-fixture: writes the synthetic plate package used by tests and
// by the demo before the full precompute is available.

#include "synthetic_package.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

int main(int argc, char** argv) {
  CLI::App app{
      "Write the synthetic 'plate' scene package (analytic modes, damped-oscillation "
      "IRFs, closed-form transfer) used as a test fixture."};
  std::string out;
  phasecast::testing::PlateOptions o;
  bool no_appearance = false;
  app.add_option("-o,--output", out, "package file to write (.h5)")->required();
  app.add_option("--grid", o.grid, "plate points per side")
      ->check(CLI::Range(3, 1000))
      ->capture_default_str();
  app.add_option("--rank", o.rank_u, "number of displacement modes r_u")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--irfs", o.irfs_per_entry, "IRFs per palette entry")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--irf-length", o.irf_length, "state nodes per IRF")
      ->check(CLI::Range(2, 100000))
      ->capture_default_str();
  app.add_option("--seed", o.seed, "random seed of IRF phases and amplitudes")->capture_default_str();
  app.add_flag("--no-appearance", no_appearance, "omit the /appearance block");
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-make-fixture"))
    return *status;
  o.appearance = !no_appearance;
  try {
    phasecast::core::write_package(phasecast::testing::make_plate_package(o), out);
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-make-fixture: {}\n", e.what());
    return 1;
  }
  fmt::print("wrote {}\n", out);
  return 0;
}
