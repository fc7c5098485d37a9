// `phasecast-precompute transfer`: diffuse PRT of any OBJ mesh into an HDF5
// transfer file (docs/transfer.md).

#include "commands.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/appearance/transfer_file.h"
#include "phasecast/precompute/distributed/ranks.h"

#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

namespace phasecast::precompute::tools {
namespace {

struct TransferArgs {
  std::string mesh;
  std::string output;
  std::string mode = "shadowed";
  int rays = 1024;
  int bounces = 2;
  std::string albedo = "0.8,0.8,0.8";
  int threads = 0;
  bool double_sided = false;
  bool quiet = false;
};

std::array<float, 3> parse_albedo(const std::string& text) {
  std::array<float, 3> rgb{};
  size_t start = 0;
  for (int c = 0; c < 3; ++c) {
    const size_t comma = text.find(',', start);
    if ((c < 2) != (comma != std::string::npos)) break;
    const std::string part = text.substr(start, c < 2 ? comma - start : std::string::npos);
    size_t used = 0;
    float value = 0;
    try {
      value = std::stof(part, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (part.empty() || used != part.size()) break;
    rgb[static_cast<size_t>(c)] = value;
    if (c == 2) return rgb;
    start = comma + 1;
  }
  throw std::invalid_argument(fmt::format("--albedo '{}': expected three numbers R,G,B in [0, 1]", text));
}

// Stage, done/total and ETA through the one progress printer.
auto progress_printer(bool quiet) {
  auto bar = std::make_shared<core::ProgressBar>("transfer");
  auto stage = std::make_shared<std::string>();
  return [=](const char* name, long done, long total) {
    if (quiet) return;
    if (*stage != name) bar->restart(fmt::format("transfer: {} points", *stage = name));
    bar->update(done, total);
    if (done == total) bar->finish();
  };
}

void run_transfer(const TransferArgs& a) {
  TransferOptions options;
  options.mode = parse_transfer_mode(a.mode);
  options.rays = a.rays;
  options.bounces = a.bounces;
  options.albedo = parse_albedo(a.albedo);
  options.threads = a.threads;
  options.progress = progress_printer(a.quiet);
  validate_transfer_options(options);

  TransferMesh mesh = load_obj_mesh(a.mesh);
  if (a.double_sided) mesh = make_double_sided(mesh);
  const auto start = std::chrono::steady_clock::now();
  TransferFile file;
  file.transfer = compute_transfer(mesh.positions, mesh.triangles, mesh.normals, options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  file.positions = std::move(mesh.positions);
  file.normals = std::move(mesh.normals);
  file.options = options;
  write_transfer_file(file, a.output);
  if (!a.quiet) {
    fmt::print(stderr, "transfer: {} points, {} mode, {} rays, {:.2f} s -> {}\n", file.positions.rows(),
               transfer_mode_name(options.mode), options.rays, seconds, a.output);
  }
}

}  // namespace

void add_transfer_command(CLI::App& app) {
  auto args = std::make_shared<TransferArgs>();
  CLI::App* cmd = app.add_subcommand(
      "transfer",
      "Diffuse precomputed radiance transfer (SH order 4, RGB) of a static OBJ mesh, written to HDF5: "
      "/positions, /normals, /transfer (S x 3 x 16).");
  cmd->add_option("mesh", args->mesh, "input mesh (.obj); scene points are its vertices")->required();
  cmd->add_option("-o,--output", args->output, "output transfer file (.h5)")->required();
  cmd->add_option("--mode", args->mode, "unshadowed | shadowed | interreflected")->capture_default_str();
  cmd->add_option("--rays", args->rays, "directions per point (fixed sphere set)")->capture_default_str();
  cmd->add_option("--bounces", args->bounces, "interreflection bounces (interreflected mode)")
      ->capture_default_str();
  cmd->add_option("--albedo", args->albedo, "diffuse albedo R,G,B in [0, 1]")->capture_default_str();
  cmd->add_option("--threads", args->threads, "worker threads (0: all cores)")->capture_default_str();
  cmd->add_flag("--double-sided", args->double_sided,
                "also make the back side of every face scene points (thin surfaces)");
  cmd->add_flag("-q,--quiet", args->quiet, "no progress output");
  cmd->callback([args] {
    Ranks::world().require_one_process("transfer");
    run_transfer(*args);
  });
}

}  // namespace phasecast::precompute::tools
