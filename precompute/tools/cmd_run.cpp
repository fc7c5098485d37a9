// phasecast-precompute run: sample -> reduce -> appearance in one command.

#include "commands.h"
#include "phasecast/core/package.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/pipeline/adaptive_sampling.h"
#include "phasecast/precompute/pipeline/report_text.h"
#include "stage_options.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::precompute::tools {
namespace {

struct Options {
  std::string scene;
  std::string output;
  SampleStageOptions sample;
  ReduceStageOptions reduce;
  AppearanceChoices appearance;
  std::optional<double> until_fidelity;  // the median NRMSE target of adaptive sampling
  AdaptiveOptions adaptive;
  int held_out_schedules = -1;      // -1: 20 with --until-fidelity, else none
  std::uint64_t fidelity_seed = 0;  // 0: derived from --seed (below 2^53: the package stores it as a double)
  bool allow_missing_entries = false;  // accept a package in which an entry has no IRF
  bool allow_rest_problems = false;    // accept a scene whose rest trials find a problem
  bool no_check = false;               // skip check's trials and fidelity line at the end
};

std::vector<std::string> entries_without_irfs(const core::ScenePackage& p) {
  std::vector<int> irfs(static_cast<size_t>(p.palette.size()), 0);
  for (const auto e : p.portrait.irf_palette) ++irfs[static_cast<size_t>(e)];
  std::vector<std::string> names;
  for (size_t e = 0; e < irfs.size(); ++e)
    if (irfs[e] == 0) names.push_back(p.palette.names[e]);
  return names;
}

// A palette entry without an IRF cannot be played: the server refuses it.
// The package stays written (nothing computed is lost); run fails naming them.
void check_every_entry_sampled(const core::ScenePackage& p, const Options& o) {
  const auto names = entries_without_irfs(p);
  const auto count = names.size();
  if (count == 0 || o.allow_missing_entries) return;
  const std::string missing = fmt::format("'{}'", fmt::join(names, "', '"));
  throw std::runtime_error(
      fmt::format("{}: no IRF of palette {} {} (the server would refuse {}): sample more (--irfs-per-chain, "
                  "--chains) or let {} follow more entries ('after'); the package is written, "
                  "--allow-missing-entries accepts it",
                  o.output, count > 1 ? "entries" : "entry", missing, count > 1 ? "them" : "it",
                  count > 1 ? "them" : "it"));
}

// check's trials: a rest that moves, or a push and a stop that end elsewhere
// (a neutral mode), is a state the served scene cannot know, since a package
// has one rest; playback snaps back. Where run measured no held-out figures
// and every entry can be played, check's short fidelity estimate follows,
// with what it suggests. Only a rest problem fails run; the package stays.
void check_scene_health(const Scene& scene, const core::ScenePackage& package, bool measured,
                        const Options& o) {
  const bool playable = entries_without_irfs(package).empty();
  SceneCheckOptions options;
  options.list_irfs = false;
  // Half of check's schedules: on the default door each costs about 30 s of simulation.
  options.fidelity_schedules = measured ? 0 : 2;
  const SceneCheck c = check_and_report(scene, playable ? &package : nullptr, options);
  const int n = c.problems();
  if (n == 0 || o.allow_rest_problems) return;
  throw std::runtime_error(
      fmt::format("{}: the rest trials found {} problem{} in {} (above, each with its fix); the package is "
                  "written, --allow-rest-problems accepts it",
                  o.output, n, n > 1 ? "s" : "", o.scene));
}

// The held-out schedules' stream: never the sampler's, never the guides'.
std::uint64_t held_out_seed(const Options& o) {
  return o.fidelity_seed != 0 ? o.fidelity_seed : 0x74657374ULL + 7919 * o.sample.sampling.seed;  // "test"
}

void add_fidelity_options(CLI::App* cmd, Options& o) {
  cmd->add_flag("--allow-missing-entries", o.allow_missing_entries,
                "exit 0 even when a palette entry got no IRF (the server refuses such an entry)");
  cmd->add_flag("--allow-rest-problems", o.allow_rest_problems,
                "exit 0 even when the rest trials at the end (check's) find a rest that moves or a neutral "
                "mode (the served scene snaps back to its one rest)");
  cmd->add_flag(
      "--no-check", o.no_check,
      "skip the rest trials and the fidelity line at the end (benchmarks; scenes whose trials are slow: "
      "check runs them on its own)");
  cmd->add_option(
         "--until-fidelity", o.until_fidelity,
         "sample until random guide schedules, and fresh ones after them, play at this median NRMSE "
         "(90th percentile + 0.1, 95 % of moving segments in range), spending new IRFs where playback "
         "departs from the simulation (docs/sampling.md, \"Adaptive sampling\"); needs --budget-irfs or "
         "--budget-minutes")
      ->check(CLI::Range(1e-6, 10.0));
  cmd->add_option("--budget-irfs", o.adaptive.budget_irfs,
                  "with --until-fidelity: IRFs to sample at most, all rounds")
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--budget-minutes", o.adaptive.budget_minutes,
                  "with --until-fidelity: start no round after this many minutes")
      ->check(CLI::Range(0.0, 1e7));
  cmd->add_option(
         "--guide-schedules", o.adaptive.guide_schedules,
         "with --until-fidelity: random schedules, drawn and simulated once, every round is judged on")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  cmd->add_option(
         "--fresh-schedules", o.adaptive.fresh_schedules,
         "with --until-fidelity: random schedules the package plays each time the guide ones meet the "
         "target (no chain was aimed at them); sampling stops when these alone meet it too, else they "
         "join the guide schedules (0: stop when the guide schedules meet it)")
      ->check(CLI::Range(0, 10000))
      ->capture_default_str();
  cmd->add_option(
         "--directed-chains", o.adaptive.directed_chains,
         "with --until-fidelity: the most directed chains a round adds once every palette entry has "
         "IRFs, up to --chains (0: --chains; a round that mends entries without IRFs adds up to --chains)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  cmd->add_option("--directed-extra-irfs", o.adaptive.directed_extra_irfs,
                  "with --until-fidelity: random IRFs a directed chain draws after its segment's and the one "
                  "before it")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->add_option("--held-out-schedules", o.held_out_schedules,
                  "random schedules (their own seed) the finished package is measured on (default: 20 with "
                  "--until-fidelity, else 0)")
      ->check(CLI::Range(0, 10000));
  cmd->add_option("--fidelity-seed", o.fidelity_seed, "seed of the held-out schedules (0: from --seed)")
      ->check(CLI::Range(std::uint64_t{0}, std::uint64_t{1} << 53));
}

// Samples at random, or round by round until the fidelity target (then the
// figures the package stores of it).
SampleReport sample(const Scene& scene, Options& o, const SampleStageOptions& first,
                    const std::filesystem::path& orbits, core::PlaybackFidelity& adaptive) {
  if (!o.until_fidelity) return run_sample_stage(scene, first, orbits);
  o.adaptive.target = FidelityTarget{*o.until_fidelity, *o.until_fidelity + 0.1, 0.95};
  const AdaptiveReport a = run_adaptive_sampling(scene, first, o.reduce, o.adaptive, orbits);
  if (a.writer) fmt::print("{}", adaptive_report_text(a));
  adaptive.target_median_nrmse = static_cast<float>(*o.until_fidelity);
  adaptive.target_met = a.met;
  adaptive.rounds = static_cast<std::int32_t>(a.rounds.size());
  adaptive.sampled_irfs = a.rounds.empty() ? 0 : a.rounds.back().irfs;
  return a.sampled;
}

// The held-out figures, stored in the package beside what adaptive sampling did.
void store_fidelity(const FidelityFigures& f, core::PlaybackFidelity fidelity, core::ScenePackage package,
                    const std::filesystem::path& path) {
  fidelity.schedules = f.schedules;
  fidelity.items = f.items;
  fidelity.seed = static_cast<double>(f.seed);
  fidelity.median_nrmse = static_cast<float>(f.median_nrmse);
  fidelity.p90_nrmse = static_cast<float>(f.p90_nrmse);
  fidelity.moving = f.moving;
  fidelity.moving_within = f.moving_within;
  fidelity.switches = f.switches;
  fidelity.switches_within = f.switches_within;
  package.fidelity = fidelity;
  core::write_package(package, path);
}

}  // namespace

void add_run_command(CLI::App& app) {
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "run",
      "Build a scene package from a scene file: sample IRFs, reduce, then the appearance stage (resumable); "
      "then check's rest trials and a short fidelity estimate (docs/check.md). Exit 1 when an entry has no "
      "IRF or the trials find a rest problem; the package is written either way.");
  cmd->add_option("scene", o->scene, "scene file (.toml)")->required();
  cmd->add_option("-o,--output", o->output, "scene package to write (.h5)")->required();
  add_sample_options(cmd, o->sample);
  add_reduce_options(cmd, o->reduce);
  add_appearance_options(cmd, o->appearance);
  add_fidelity_options(cmd, *o);
  cmd->callback([o] {
    const auto scene = phasecast::precompute::load_scene_file(o->scene);
    // Bad appearance options fail before the sampling hours, not after.
    if (!o->appearance.skip) appearance_stage_options(scene, o->appearance);
    auto sample = o->sample;
    if (sample.work_dir.empty()) sample.work_dir = o->output + ".work";
    const std::filesystem::path orbits = sample.work_dir / "orbits.h5";
    check_save_transfers(o->appearance, {orbits, o->output});
    if (o->until_fidelity) check_adaptive_options(o->adaptive, sample);
    core::PlaybackFidelity fidelity;
    const auto sampled = tools::sample(scene, *o, sample, orbits, fidelity);
    if (sampled.writer) fmt::print("{}", sample_report_text(sampled));
    const auto reduced = run_reduce_stage(scene, o->reduce, o->appearance, orbits, o->output);
    if (reduced.writer) fmt::print("{}", reduce_report_text(reduced));
    check_every_entry_sampled(reduced.package, *o);
    const int held_out = o->held_out_schedules >= 0 ? o->held_out_schedules : (o->until_fidelity ? 20 : 0);
    if (held_out > 0) {
      core::ProgressBar bar{"held-out schedules"};
      const auto f =
          measure_fidelity(scene, reduced.package, held_out_seed(*o), held_out, o->adaptive.schedule_items,
                           [&bar](int done, int total) { bar.update(done, total); });
      bar.finish();
      if (reduced.writer) {
        fmt::print("{}", fidelity_text(f, "held-out"));
        store_fidelity(f, fidelity, reduced.package, o->output);
      }
    }
    if (reduced.writer && !o->no_check) check_scene_health(scene, reduced.package, held_out > 0, *o);
  });
}

}  // namespace phasecast::precompute::tools
