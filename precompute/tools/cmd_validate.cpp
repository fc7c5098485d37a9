// phasecast-precompute validate: playback fidelity of a package against the
// full simulation of the same schedules (docs/validation.md).

#include "commands.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/validation/playback.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <fstream>
#include <memory>
#include <string>

namespace phasecast::precompute::tools {
namespace {

struct ValidateOptions {
  std::string scene;
  std::vector<std::string> packages;
  std::vector<std::string> schedules;
  int random = 0;
  std::uint64_t seed = 1;
  int items = 6;
  std::string json;
  bool no_intersections = false;
};

void print_schedule(const ScheduleFigures& g) {
  fmt::print("  {:<8} {:>6} {:>7} {:>7} {:>12}  {}\n", "segment", "frames", "NRMSE", "motion", "sim mm/frame",
             "");
  const double typical = typical_motion(g);
  for (const auto& s : g.segments) {
    fmt::print("  {:<8} {:>6} {:>7.3f} {:>7.3f} {:>12.3f}  {}{}\n", s.entry, s.frames, s.nrmse,
               s.motion_ratio, 1e3 * s.simulated_motion, is_moving(s, typical) ? "moving" : "",
               s.refused.empty() ? "" : " REFUSED: " + s.refused);
  }
  int within = 0;
  for (const auto& s : g.switches) within += s.ratio() <= kJumpRatio;
  std::vector<double> ends = g.irf_end_speeds;
  std::sort(ends.begin(), ends.end());
  fmt::print(
      "  whole: NRMSE {:.3f}, motion ratio {:.3f}; switches {} ({} with jump <= {}x local motion); "
      "IRF ends {} (median speed {:.4f} m/s, simulation median {:.4f} m/s); self-intersecting: {} frames, "
      "at most {} pairs\n",
      g.nrmse, g.motion_ratio, g.switches.size(), within, kJumpRatio, ends.size(),
      ends.empty() ? 0.0 : ends[ends.size() / 2], g.median_simulated_speed, g.frames_with_intersections,
      g.max_intersecting_pairs);
}

void print_summary(const std::string& what, const nlohmann::json& j) {
  fmt::print(
      "{}: median NRMSE {:.3f}, 90th percentile {:.3f}; moving segments with motion ratio in [{}, {}]: "
      "{}/{}; "
      "switches with jump <= {}x local motion: {}/{}; served frames with self-intersections: {}\n",
      what, j["median_nrmse"].get<double>(), j["p90_nrmse"].get<double>(), kMotionLow, kMotionHigh,
      j["moving_segments_within"].get<int>(), j["moving_segments"].get<int>(), kJumpRatio,
      j["switches_within"].get<int>(), j["switches"].get<int>(), j["frames_with_intersections"].get<int>());
}

struct Schedule {
  std::string kind;  // "given" or "random"
  std::vector<ScheduleItem> items;
};

std::vector<Schedule> schedules_to_play(const ValidateOptions& o, const Scene& scene) {
  std::vector<std::string> given = o.schedules;
  if (given.empty() && o.random == 0) {
    if (scene.standard_schedule.empty())
      throw std::invalid_argument(fmt::format(
          "validate: {} has no [validation] schedule; expected --schedule \"...\" and/or --random K",
          o.scene));
    given.push_back(scene.standard_schedule);
  }
  std::vector<Schedule> work;
  for (const auto& text : given) work.push_back({"given", parse_schedule(text, scene)});
  const PaletteRules rules = make_palette_rules(scene);
  for (int k = 0; k < o.random; ++k)
    work.push_back({"random", random_schedule(rules, scene.simulation.frame_dt, o.seed, k, o.items)});
  return work;
}

// One package's figures over every schedule, as the report and the summary lines show them.
struct PackageReport {
  std::string path;
  std::shared_ptr<const core::ScenePackage> package;
  nlohmann::json schedules = nlohmann::json::array();
  ValidationSummary given, random;
};

// Every package is read and checked against the scene before anything is simulated.
std::vector<PackageReport> read_packages(const ValidateOptions& o, const Scene& scene) {
  std::vector<PackageReport> out;
  for (const auto& path : o.packages) {
    auto package = std::make_shared<const core::ScenePackage>(core::read_package(path));
    check_package_of(scene, *package, path);
    PackageReport& r = out.emplace_back();
    r.path = path;
    r.package = std::move(package);
  }
  return out;
}

void write_json(const ValidateOptions& o, const Scene& scene, const std::vector<PackageReport>& reports) {
  const auto report_of = [&](const PackageReport& r) {
    nlohmann::json j = {
        {"scene", scene.name}, {"package", r.path}, {"seed", o.seed}, {"schedules", r.schedules}};
    if (r.given.nrmse.size()) j["summary_given"] = r.given.to_json();
    if (o.random > 0) j["summary_random"] = r.random.to_json();
    return j;
  };
  nlohmann::json report;
  if (reports.size() == 1) {
    report = report_of(reports.front());
  } else {
    report = {{"scene", scene.name}, {"seed", o.seed}, {"packages", nlohmann::json::array()}};
    for (const auto& r : reports) report["packages"].push_back(report_of(r));
  }
  std::ofstream out(o.json);
  out << report.dump(2) << "\n";
  out.close();
  if (!out) throw std::runtime_error(fmt::format("validate: cannot write --json '{}'", o.json));
  fmt::print("wrote {}\n", o.json);
}

void run_validate(const ValidateOptions& o) {
  const Scene scene = load_scene_file(o.scene);
  std::vector<PackageReport> reports = read_packages(o, scene);
  const std::vector<Schedule> work = schedules_to_play(o, scene);
  fmt::print("validate {}: {} against the full simulation, {} schedule(s)\n", scene.name,
             fmt::join(o.packages, ", "), work.size());
  ValidationOptions v;
  v.intersections = !o.no_intersections;
  for (size_t i = 0; i < work.size(); ++i) {
    const auto& [kind, schedule] = work[i];
    fmt::print("schedule {}/{} ({}): {}\n", i + 1, work.size(), kind, schedule_text(scene, schedule));
    core::ProgressBar bar(fmt::format("simulate {}/{}", i + 1, work.size()));
    const SimulatedSchedule truth =
        simulate_truth(scene, schedule, [&bar](int done, int total) { bar.update(done, total); });
    bar.finish();
    for (auto& r : reports) {
      if (reports.size() > 1) fmt::print(" {}:\n", r.path);
      const ScheduleFigures g = compare_playback(scene, r.package, truth, v);
      print_schedule(g);
      (kind == "given" ? r.given : r.random).add(g);
      auto j = to_json(g);
      j["kind"] = kind;
      r.schedules.push_back(std::move(j));
    }
  }
  for (const auto& r : reports) {
    const std::string of = reports.size() > 1 ? r.path + ": " : "";
    if (r.given.nrmse.size()) print_summary(of + "given schedules", r.given.to_json());
    if (o.random > 0) print_summary(of + "random schedules", r.random.to_json());
  }
  if (!o.json.empty()) write_json(o, scene, reports);
}

}  // namespace

void add_validate_command(CLI::App& app) {
  auto o = std::make_shared<ValidateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "validate",
      "Measure playback against the truth: simulate schedules with the full simulator, play the same entries "
      "at "
      "the same frames through the server's synthesis engine, and report NRMSE, motion ratios, blend jumps, "
      "speeds at IRF ends and self-intersections.");
  cmd->add_option("scene", o->scene, "scene file (.toml)")->required();
  cmd->add_option("packages", o->packages,
                  "scene packages of that scene (.h5); several are measured on the same simulations, each "
                  "schedule simulated once")
      ->required();
  cmd->add_option(
      "--schedule", o->schedules,
      "schedule \"open 0.8; stop 1.5; ...\" (repeatable; default: the scene's [validation] schedule)");
  cmd->add_option("--random", o->random,
                  "also this many random schedules obeying the palette rules and range")
      ->check(CLI::Range(0, 10000));
  cmd->add_option("--seed", o->seed, "seed of the random schedules")->capture_default_str();
  cmd->add_option("--items", o->items, "entries per random schedule")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--json", o->json, "write every figure to this JSON file");
  cmd->add_flag("--no-intersections", o->no_intersections, "skip the exact self-intersection count");
  cmd->callback([o] {
    Ranks::world().require_one_process("validate");
    run_validate(*o);
  });
}

}  // namespace phasecast::precompute::tools
