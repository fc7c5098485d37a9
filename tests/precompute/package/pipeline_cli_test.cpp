// phasecast-precompute run / sample / reduce as a user runs them: the tiny
// scene end to end, inspect accepting the package, a stopped run resumed into
// the same package bytes, and one-line errors.

#include "fresh_schedule_run.h"
#include "phasecast/core/package.h"
#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "run_tool.h"
#include "scene_files.h"
#include "source_tree.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <sys/wait.h>
#include <algorithm>
#include <chrono>
#include <csignal>
#include <regex>
#include <set>
#include <thread>

namespace phasecast {
namespace {

using testing::run_tool;
using testing::scratch_dir;
using testing::tiny_scene_path;

// A sample this thin leaves an entry without IRFs, which run would refuse (RunFailsNamingAnEntryWithoutIrfs).
const std::vector<std::string> kSmall = {"--chains",   "2",  "--irfs-per-chain",       "3", "--seed", "4",
                                         "--max-rank", "20", "--allow-missing-entries"};

std::vector<std::string> args(std::vector<std::string> head, const std::vector<std::string>& tail = kSmall) {
  head.insert(head.end(), tail.begin(), tail.end());
  return head;
}

bool one_line(const std::string& s) {
  return !s.empty() && s.find('\n') == s.size() - 1;
}

// check as a user runs it: the flag's neutral mode fails it in one line;
// with a package, IRFs per entry and a fidelity estimate.
TEST(PipelineCli, CheckNamesTheNeutralModeAndReadsAPackage) {
  const auto flag =
      run_tool("phasecast-precompute",
               {"check", (testing::source_dir() / "tests/data/scenes/flag_pole.toml").string()});
  EXPECT_EQ(flag.exit_code, 1);
  EXPECT_NE(flag.out.find("a neutral mode: 'flag' turned"), std::string::npos) << flag.out;
  EXPECT_NE(flag.err.find("1 problem found"), std::string::npos) << flag.err;
  const auto door =
      run_tool("phasecast-precompute",
               {"check", tiny_scene_path().string(), "--package",
                (testing::source_dir() / "tests/data/packages/cloth_door.h5").string(), "--schedules", "2"});
  EXPECT_EQ(door.exit_code, 0) << door.err;
  EXPECT_NE(door.out.find("palette 'open': 3 IRFs in the package"), std::string::npos) << door.out;
  EXPECT_NE(door.out.find("fidelity (2 random schedules of 4 entries, seed 7): median NRMSE"),
            std::string::npos)
      << door.out;
  // A package the server cannot play whole: the entries named, no fidelity of schedules it would refuse.
  const auto dir = scratch_dir("cli_check_thin");
  const auto thin = (dir / "thin.h5").string();
  ASSERT_EQ(run_tool("phasecast-precompute",
                     {"run", tiny_scene_path().string(), "-o", thin, "--chains", "1", "--irfs-per-chain", "1",
                      "--no-appearance", "--allow-missing-entries"})
                .exit_code,
            0);
  const auto t = run_tool("phasecast-precompute", {"check", tiny_scene_path().string(), "--package", thin});
  EXPECT_EQ(t.exit_code, 1);
  EXPECT_NE(t.out.find("palette 'close': no IRF in the package, so the server refuses it; fix: sample more"),
            std::string::npos)
      << t.out;
  EXPECT_NE(t.out.find("palette 'open': 1 IRF in the package"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("fidelity: not estimated"), std::string::npos) << t.out;
  EXPECT_NE(t.err.find("2 problems found"), std::string::npos) << t.err;
  // A package of another scene is refused in one line naming both.
  const auto other = run_tool("phasecast-precompute",
                              {"check", tiny_scene_path().string(), "--package",
                               (testing::source_dir() / "tests/data/packages/plant_pot.h5").string()});
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_TRUE(one_line(other.err)) << other.err;
  EXPECT_NE(other.err.find("is of scene 'plant_pot_tiny' with 3 palette entries;"), std::string::npos)
      << other.err;
}

// Every template of init simulates its [validation] schedule as written and
// passes check (its rest is a rest, every entry returns to it).
TEST(PipelineCli, InitTemplatesSimulateAsWrittenAndPassCheck) {
  const auto dir = scratch_dir("pipeline_init");
  for (const std::string name : {"door-cloth", "hanging-banner", "pushed-plant", "jolted-solid"}) {
    const std::string scene = (dir / (name + ".toml")).string();
    const auto init = run_tool("phasecast-precompute", {"init", "--template", name, scene, "--force"});
    ASSERT_EQ(init.exit_code, 0) << init.err;
    EXPECT_NE(init.out.find("next: phasecast-precompute simulate " + scene + " --schedule"),
              std::string::npos);
    const auto check = run_tool("phasecast-precompute", {"check", scene});
    EXPECT_EQ(check.exit_code, 0) << name << ": " << check.out << check.err;
    EXPECT_EQ(check.out.find("no quiet palette entry"), std::string::npos)
        << name << ": every template has one";
    // The [validation] schedule init names as the next step, simulated as written.
    const auto from = init.out.find("--schedule \"") + 12;
    const std::string schedule = init.out.substr(from, init.out.find('"', from) - from);
    const auto sim = run_tool("phasecast-precompute", {"simulate", scene, "--schedule", schedule, "-o",
                                                       (dir / (name + ".h5")).string()});
    EXPECT_EQ(sim.exit_code, 0) << name << ": " << sim.err;
  }
  const auto again = run_tool("phasecast-precompute",
                              {"init", "--template", "door-cloth", (dir / "door-cloth.toml").string()});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_TRUE(one_line(again.err)) << again.err;
  EXPECT_NE(again.err.find("exists (expected a new file, or --force to replace it)"), std::string::npos);
  const auto unknown =
      run_tool("phasecast-precompute", {"init", "--template", "flag", (dir / "flag.toml").string()});
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_NE(unknown.err.find("--template 'flag' is unknown (expected one of door-cloth, hanging-banner, "
                             "pushed-plant, jolted-solid)"),
            std::string::npos)
      << unknown.err;
}

TEST(PipelineCli, RunWritesAPackageThatInspectAccepts) {
  const auto dir = scratch_dir("cli_run");
  const auto pkg = (dir / "tiny.h5").string();
  const auto r = run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("r_u = "), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("sample IRFs: 6/6 (100%), "), std::string::npos) << r.err;
  const auto inspect = run_tool("phasecast-inspect", {pkg});
  ASSERT_EQ(inspect.exit_code, 0) << inspect.err;
  EXPECT_NE(inspect.out.find("n_irf = 6 IRFs"), std::string::npos) << inspect.out;
  EXPECT_NE(inspect.out.find("displacement r_u = "), std::string::npos) << inspect.out;
  const auto p = core::read_package(pkg);
  EXPECT_EQ(p.portrait.irf_count(), 6);
  // Per entry, the kept IRFs are the package's: counted again from /portrait/irf_palette.
  for (int e = 0; e < p.palette.size(); ++e) {
    const auto kept = std::count(p.portrait.irf_palette.begin(), p.portrait.irf_palette.end(), e);
    EXPECT_NE(r.out.find(fmt::format("'{}' ", p.palette.names[static_cast<size_t>(e)])), std::string::npos);
    EXPECT_NE(r.out.find(fmt::format("'{}' {} sampled, {} kept", p.palette.names[static_cast<size_t>(e)],
                                     kept, kept)),
              std::string::npos)
        << "nothing is dropped from this sample: " << r.out;
  }
  // A strict dead-end filter drops one of 'close''s two IRFs, counted by its reason and named.
  const auto strict =
      run_tool("phasecast-precompute", {"run", tiny_scene_path().string(), "-o", (dir / "strict.h5").string(),
                                        "--chains", "2", "--irfs-per-chain", "4", "--seed", "2",
                                        "--no-appearance", "--no-check", "--dead-end-fraction", "0.001"});
  ASSERT_EQ(strict.exit_code, 0) << strict.err;
  EXPECT_NE(strict.out.find("'close' 2 sampled, 1 kept (0 short, 1 dead ends dropped)"), std::string::npos)
      << strict.out;
  EXPECT_NE(strict.err.find("('close'): dead end"), std::string::npos) << strict.err;
}

// run ends with check's trials: the tiny door returns to its rest, and with
// every entry sampled check's fidelity estimate follows; the flag turns about
// its pole and stays there, which fails run (the package is written all the
// same) unless --allow-rest-problems.
TEST(PipelineCli, RunEndsWithTheRestTrials) {
  const auto dir = scratch_dir("cli_rest_trials");
  const std::vector<std::string> quick = {
      "--chains", "1", "--irfs-per-chain", "4", "--no-appearance", "--allow-missing-entries"};
  const auto door =
      run_tool("phasecast-precompute",
               args({"run", tiny_scene_path().string(), "-o", (dir / "door.h5").string()},
                    {"--chains", "2", "--irfs-per-chain", "8", "--seed", "2", "--no-appearance"}));
  ASSERT_EQ(door.exit_code, 0) << door.err;
  EXPECT_NE(door.out.find("return: 'open 0.62; stop 3.00': moved up to"), std::string::npos) << door.out;
  EXPECT_NE(door.out.find("fidelity (2 random schedules of 4 entries, seed 7): median NRMSE"),
            std::string::npos)
      << door.out;
  EXPECT_EQ(door.out.find("IRFs in the package"), std::string::npos)
      << "run has printed the counts: " << door.out;
  const auto scene = (testing::source_dir() / "tests/data/scenes/flag_pole.toml").string();
  const auto pkg = (dir / "flag.h5").string();
  const auto flag = run_tool("phasecast-precompute", args({"run", scene, "-o", pkg}, quick));
  EXPECT_EQ(flag.exit_code, 1);
  EXPECT_NE(flag.out.find("a neutral mode: 'flag' turned"), std::string::npos) << flag.out;
  EXPECT_TRUE(one_line(flag.err.substr(flag.err.rfind("phasecast-precompute: ")))) << flag.err;
  EXPECT_NE(
      flag.err.find("flag.h5: the rest trials found 1 problem in " + scene +
                    " (above, each with its fix); the package is written, --allow-rest-problems accepts it"),
      std::string::npos)
      << flag.err;
  EXPECT_GT(core::read_package(pkg).portrait.irf_count(), 0) << "the package is written all the same";
  auto allowed = quick;
  allowed.push_back("--allow-rest-problems");
  EXPECT_EQ(run_tool("phasecast-precompute", args({"run", scene, "-o", pkg}, allowed)).exit_code, 0);
  auto unchecked = quick;
  unchecked.push_back("--no-check");
  const auto skipped = run_tool("phasecast-precompute", args({"run", scene, "-o", pkg}, unchecked));
  EXPECT_EQ(skipped.exit_code, 0) << skipped.err;
  EXPECT_EQ(skipped.out.find("return:"), std::string::npos) << "--no-check plays no trial: " << skipped.out;
}

// One IRF from rest cannot be a 'stop' (it follows open or close): run writes
// the package, then fails naming the entries the server would refuse.
TEST(PipelineCli, RunFailsNamingAnEntryWithoutIrfs) {
  const auto dir = scratch_dir("cli_missing_entry");
  const auto pkg = (dir / "thin.h5").string();
  const std::vector<std::string> thin = {"--chains", "1", "--irfs-per-chain", "1", "--no-appearance"};
  const auto r = run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg}, thin));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("thin.h5: no IRF of palette entries 'close', 'stop' (the server would refuse them)"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("--allow-missing-entries accepts it"), std::string::npos) << r.err;
  EXPECT_EQ(core::read_package(pkg).portrait.irf_count(), 1) << "the package is written all the same";
  auto allowed = thin;
  allowed.push_back("--allow-missing-entries");
  EXPECT_EQ(run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg}, allowed))
                .exit_code,
            0);
}

// --until-fidelity samples in rounds of directed chains within its budget,
// says why it stopped, and the package stores the held-out figures; the
// same options give the same package bytes.
TEST(PipelineCli, UntilFidelitySamplesInRoundsWithinItsBudget) {
  const auto dir = scratch_dir("cli_until_fidelity");
  const std::vector<std::string> adaptive = {"--chains",
                                             "2",
                                             "--irfs-per-chain",
                                             "3",
                                             "--seed",
                                             "4",
                                             "--max-rank",
                                             "20",
                                             "--no-appearance",
                                             "--until-fidelity",
                                             "0.001",
                                             "--budget-irfs",
                                             "12",
                                             "--guide-schedules",
                                             "3",
                                             "--held-out-schedules",
                                             "4"};
  const auto pkg = (dir / "a.h5").string();
  const auto r =
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg}, adaptive));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("adaptive round 0: 6 IRFs; fidelity (guide, 3 random schedules of 4 entries"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("adaptive round 1: "), std::string::npos) << r.out;
  // Every round is judged on the same guide schedules (drawn and simulated once).
  const std::regex guide_seed{R"(adaptive round \d+: .*fidelity \(guide, .*, seed (\d+)\))"};
  std::set<std::string> guide_seeds;
  int rounds = 0;
  for (auto it = std::sregex_iterator(r.out.begin(), r.out.end(), guide_seed); it != std::sregex_iterator();
       ++it, ++rounds)
    guide_seeds.insert((*it)[1].str());
  EXPECT_GE(rounds, 2) << r.out;
  EXPECT_EQ(guide_seeds.size(), 1u) << r.out;
  // Round 1: one directed chain (--directed-chains' default) of 4 IRFs (the
  // item before the segment, the segment's and --directed-extra-irfs' 2).
  EXPECT_NE(r.out.find("adaptive round 1: 10 IRFs (1 directed chain added)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("adaptive sampling: IRF budget spent after "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fidelity (held-out, 4 random schedules of 4 entries"), std::string::npos) << r.out;
  // Guide schedules (simulated in round 0, played each round) and held-out ones: minutes on a large scene.
  EXPECT_NE(r.err.find("round 1 guide schedules: 3/3 (100%)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("held-out schedules: 4/4 (100%)"), std::string::npos) << r.err;
  const auto p = core::read_package(pkg);
  ASSERT_TRUE(p.fidelity && p.fidelity->target_median_nrmse);
  EXPECT_EQ(p.fidelity->schedules, 4);
  EXPECT_FALSE(p.fidelity->target_met);
  EXPECT_GE(p.fidelity->rounds, 2);
  EXPECT_GT(p.fidelity->sampled_irfs, 6);
  EXPECT_LE(p.fidelity->sampled_irfs, 12);
  EXPECT_LE(p.portrait.irf_count(), p.fidelity->sampled_irfs);  // the filter may drop some
  const auto again = (dir / "b.h5").string();
  ASSERT_EQ(run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", again}, adaptive))
                .exit_code,
            0);
  EXPECT_EQ(testing::read_file(pkg), testing::read_file(again));
  // Without a budget it refuses before sampling.
  const auto bad = run_tool("phasecast-precompute", {"run", tiny_scene_path().string(), "-o",
                                                     (dir / "c.h5").string(), "--until-fidelity", "0.1"});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("--until-fidelity needs a budget: --budget-irfs N or --budget-minutes M"),
            std::string::npos)
      << bad.err;
}

// `run` of the tiny scene towards a target it never meets, with directed
// chains of their recorded lead-in only (the segment's IRF and the one before).
testing::ToolResult run_with_single_irf_chains(const std::string& name, const std::string& budget,
                                               const std::string& guide_schedules,
                                               const std::vector<std::string>& more = {}) {
  const auto dir = scratch_dir(name);
  return run_tool("phasecast-precompute", args({"run",
                                                tiny_scene_path().string(),
                                                "-o",
                                                (dir / "a.h5").string(),
                                                "--chains",
                                                "2",
                                                "--irfs-per-chain",
                                                "3",
                                                "--seed",
                                                "4",
                                                "--max-rank",
                                                "20",
                                                "--no-appearance",
                                                "--no-check",
                                                "--allow-missing-entries",
                                                "--until-fidelity",
                                                "0.001",
                                                "--budget-irfs",
                                                budget,
                                                "--guide-schedules",
                                                guide_schedules,
                                                "--held-out-schedules",
                                                "0",
                                                "--directed-extra-irfs",
                                                "0"},
                                               more));
}

// --directed-extra-irfs sets how many random IRFs a directed chain draws
// after its segment's: with 0, round 1's chain adds 2 IRFs where the default
// adds 4 (UntilFidelitySamplesInRoundsWithinItsBudget).
TEST(PipelineCli, UntilFidelityDirectedChainsDrawTheExtraIrfsAsked) {
  const auto r = run_with_single_irf_chains("cli_directed_extra", "12", "3");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("adaptive round 1: 8 IRFs (1 directed chain added)"), std::string::npos) << r.out;
}

// --directed-chains caps the chains a round adds once every entry has IRFs:
// 0 lets round 1 aim up to --chains (2) of them, where the default aims one
// (UntilFidelityDirectedChainsDrawTheExtraIrfsAsked); more than --chains is
// refused before sampling.
TEST(PipelineCli, UntilFidelityDirectedChainsZeroAimsUpToChains) {
  const auto r = run_with_single_irf_chains("cli_directed_cap", "12", "3", {"--directed-chains", "0"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("adaptive round 1: 10 IRFs (2 directed chains added)"), std::string::npos) << r.out;
  const auto more = run_with_single_irf_chains("cli_directed_more", "12", "3", {"--directed-chains", "3"});
  EXPECT_EQ(more.exit_code, 1);
  EXPECT_NE(more.err.find("--directed-chains 3: expected at most --chains (2)"), std::string::npos)
      << more.err;
}

// A guide segment gets one directed chain: with one guide schedule of four
// entries, the rounds run out of segments to aim at long before the budget
// (a segment chosen again would take a chain per round to the end of it).
TEST(PipelineCli, UntilFidelityStopsWhenEveryBadGuideSegmentHadAChain) {
  const auto r = run_with_single_irf_chains("cli_directed_once", "40", "1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("adaptive sampling: no guide segment left that plays out of the target and has had no "
                       "directed chain after "),
            std::string::npos)
      << r.out;
}

testing::ToolResult run_tiny_toy(const std::filesystem::path& pkg, const std::vector<std::string>& options) {
  return run_tool("phasecast-precompute",
                  args({"run", testing::fresh_schedule_scene(), "-o", pkg.string()}, options));
}

core::PlaybackFidelity fidelity_of(const std::filesystem::path& pkg) {
  const auto p = core::read_package(pkg);
  EXPECT_TRUE(p.fidelity);
  return p.fidelity.value_or(core::PlaybackFidelity{});
}

// Guide figures that meet the target are checked on fresh schedules: on the
// tiny toy (seed 5) with one guide schedule, round 1's 7 IRFs play it true,
// but 4 fresh ones at a 90th percentile of 0.54. Those join the guides,
// round 2 aims a chain at them, and its 11 IRFs play the held-out schedules
// true, where the 7 that --fresh-schedules 0 stops at leave a fifth of their
// moving segments out of range.
TEST(PipelineCli, UntilFidelityChecksMetGuideFiguresOnFreshSchedules) {
  const auto dir = scratch_dir("cli_fresh");
  const auto r = run_tiny_toy(dir / "checked.h5", testing::fresh_schedule_options("4", "10"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::smatch fresh;
  ASSERT_TRUE(std::regex_search(
      r.err, fresh,
      std::regex{
          R"(adaptive round 1: 7 IRFs, 4 fresh guide schedules: median NRMSE [0-9.]+, 90th ([0-9.]+))"}))
      << r.err;
  EXPECT_GT(std::stod(fresh[1].str()), 0.25) << "the fresh schedules miss the target the guide one meets";
  EXPECT_NE(r.out.find("adaptive round 2: 11 IRFs (1 directed chain added); fidelity (guide, 5 random "
                       "schedules"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("adaptive sampling: target met on the guide schedules and on 4 fresh ones after 3 "
                       "rounds, 11 IRFs"),
            std::string::npos)
      << r.out;
  const auto u = run_tiny_toy(dir / "unchecked.h5", testing::fresh_schedule_options("0", "10"));
  ASSERT_EQ(u.exit_code, 0) << u.err;
  EXPECT_NE(u.out.find("adaptive sampling: target met on the guide schedules after 2 rounds, 7 IRFs"),
            std::string::npos)
      << u.out;
  const auto checked = fidelity_of(dir / "checked.h5"), unchecked = fidelity_of(dir / "unchecked.h5");
  EXPECT_EQ(checked.moving, unchecked.moving);  // the same held-out schedules
  EXPECT_EQ(checked.moving_within, checked.moving);
  EXPECT_LT(unchecked.moving_within, unchecked.moving * 9 / 10);
  EXPECT_LT(checked.p90_nrmse, 0.25);
  EXPECT_GT(unchecked.p90_nrmse, 0.25);
}

// Adaptive sampling against random at one budget (docs/sampling.md, "At a
// fixed budget"): 9 IRFs of the tiny toy, whose five jolts may follow one
// another in any order. Nine blind draws leave one of the five without IRFs
// in these seeds, so its held-out segments play nothing; a first round of 3
// and directed chains sent first to the entries without IRFs make every entry
// playable. Both are measured on the same held-out schedules.
class AdaptiveAgainstRandom : public ::testing::TestWithParam<int> {};

core::PlaybackFidelity held_out(const std::filesystem::path& dir, const std::string& name,
                                std::vector<std::string> sampling, int seed) {
  const auto pkg = (dir / (name + ".h5")).string();
  const std::vector<std::string> common = {"--seed",     std::to_string(seed),      "--no-appearance",
                                           "--no-check", "--allow-missing-entries", "--held-out-schedules",
                                           "10",         "--fidelity-seed",         "99"};
  sampling.insert(sampling.end(), common.begin(), common.end());
  const auto toy = (testing::source_dir() / "scenes/tiny/toy_dashboard.toml").string();
  const auto r = run_tool("phasecast-precompute", args({"run", toy, "-o", pkg}, sampling));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const auto p = core::read_package(pkg);
  EXPECT_TRUE(p.fidelity);
  return p.fidelity.value_or(core::PlaybackFidelity{});
}

TEST_P(AdaptiveAgainstRandom, NineIrfsOfTheTinyToyPlayMoreOfTheHeldOutMotionInRange) {
  const int seed = GetParam();
  const auto dir = scratch_dir(fmt::format("cli_adaptive_vs_random_{}", seed));
  const auto random = held_out(dir, "random", {"--chains", "3", "--irfs-per-chain", "3"}, seed);
  const auto adaptive = held_out(
      dir, "adaptive",
      {"--chains", "3", "--irfs-per-chain", "1", "--until-fidelity", "0.001", "--budget-irfs", "9"}, seed);
  ASSERT_EQ(adaptive.sampled_irfs, 9);
  ASSERT_EQ(random.moving, adaptive.moving);  // the same schedules, the same simulated motion
  EXPECT_GT(adaptive.moving_within, random.moving_within);
  EXPECT_EQ(adaptive.moving_within, adaptive.moving);
  EXPECT_LE(adaptive.median_nrmse, random.median_nrmse);
  EXPECT_LT(adaptive.p90_nrmse, random.p90_nrmse);
}

INSTANTIATE_TEST_SUITE_P(Seeds, AdaptiveAgainstRandom, ::testing::Values(1, 2, 3));

// Adaptive options whose first round is 4 IRFs and whose second adds 8 or 7
// more (two directed chains of 4 IRFs, or one of 7), so --stop-after-irfs 5
// (per round) stops inside the second round's last chain; a third round fills
// the budget of 14.
std::vector<std::string> adaptive_rounds(const std::string& directed_chains, const std::string& extra_irfs) {
  return {"--chains",
          "2",
          "--irfs-per-chain",
          "2",
          "--seed",
          "4",
          "-j",
          "1",
          "--max-rank",
          "20",
          "--no-appearance",
          "--no-check",
          "--allow-missing-entries",
          "--until-fidelity",
          "0.001",
          "--budget-irfs",
          "14",
          "--directed-chains",
          directed_chains,
          "--directed-extra-irfs",
          extra_irfs,
          "--guide-schedules",
          "3",
          "--held-out-schedules",
          "2"};
}

// A run stopped inside a directed round resumes from that round's
// checkpoints to the uninterrupted run's package bytes; returns the resumed
// run's stderr.
std::string expect_resume_in_a_later_round(const std::string& name, const std::vector<std::string>& options,
                                           const std::string& round_1) {
  const auto dir = scratch_dir(name);
  const auto straight = (dir / "straight.h5").string(), resumed = (dir / "resumed.h5").string();
  const auto r =
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", straight}, options));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("adaptive round 1: " + round_1 + " added)"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("adaptive round 2: 14 IRFs"), std::string::npos) << r.err;
  auto stopping = options;
  stopping.insert(stopping.end(), {"--stop-after-irfs", "5"});
  const auto stopped =
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", resumed}, stopping));
  EXPECT_EQ(stopped.exit_code, 1);
  EXPECT_NE(stopped.err.find("adaptive round 0: 4 IRFs, 3 guide schedules: "), std::string::npos)
      << stopped.err;
  EXPECT_NE(stopped.err.find("sampling stopped after 5 new IRFs"), std::string::npos) << stopped.err;
  EXPECT_FALSE(std::filesystem::exists(resumed));
  auto resuming = options;
  resuming.push_back("--resume");
  const auto again =
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", resumed}, resuming));
  EXPECT_EQ(again.exit_code, 0) << again.err;
  EXPECT_TRUE(testing::read_file(straight) == testing::read_file(resumed)) << "the package bytes differ";
  return again.err;
}

TEST(PipelineCli, UntilFidelityResumesInALaterRoundToTheSameBytes) {
  expect_resume_in_a_later_round("cli_until_fidelity_resume", adaptive_rounds("2", "2"),
                                 "12 IRFs (2 directed chains");
}

// The default --directed-chains 1: round 1 is one chain of 7 IRFs, stopped
// after its fifth; the resumed run continues it with its sixth and seventh,
// not again.
TEST(PipelineCli, UntilFidelityResumesInsideOneDirectedChainToTheSameBytes) {
  const auto err = expect_resume_in_a_later_round("cli_until_fidelity_resume_one_chain",
                                                  adaptive_rounds("1", "5"), "11 IRFs (1 directed chain");
  const auto round_1 = err.find("1 chains x 7 IRFs (directed)");
  ASSERT_NE(round_1, std::string::npos) << err;
  const auto chain = err.find("chain 0:", round_1);
  ASSERT_NE(chain, std::string::npos) << err;
  EXPECT_EQ(err.substr(chain, 16), "chain 0: 2 IRFs,") << err;
}

TEST(PipelineCli, KilledRunResumesToTheSamePackageBytes) {
  const auto dir = scratch_dir("cli_resume");
  const auto straight = (dir / "straight.h5").string(), resumed = (dir / "resumed.h5").string();
  ASSERT_EQ(
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", straight})).exit_code,
      0);
  const auto stopped =
      run_tool("phasecast-precompute",
               args({"run", tiny_scene_path().string(), "-o", resumed, "--stop-after-irfs", "2"}));
  EXPECT_EQ(stopped.exit_code, 1);
  EXPECT_NE(stopped.err.find("phasecast-precompute: sampling stopped after "), std::string::npos)
      << stopped.err;
  EXPECT_FALSE(std::filesystem::exists(resumed));
  const auto again =
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", resumed, "--resume"}));
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.err.find("(resuming)"), std::string::npos);
  // Same orbits and same package contents, bit for bit. (Not file bytes: core's HDF5 layer
  // still stamps modification times on string datasets and the root group.)
  const auto a = precompute::read_orbit_store(straight + ".work/orbits.h5");
  const auto b = precompute::read_orbit_store(resumed + ".work/orbits.h5");
  EXPECT_EQ(a.irf_palette, b.irf_palette);
  EXPECT_EQ(a.irf_length, b.irf_length);
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.velocities == b.velocities);
  const auto p = core::read_package(straight), q = core::read_package(resumed);
  EXPECT_TRUE(p.reduction.mean_shape == q.reduction.mean_shape);
  EXPECT_TRUE(p.reduction.U_u == q.reduction.U_u);
  EXPECT_TRUE(p.reduction.singular_values == q.reduction.singular_values);
  EXPECT_TRUE(p.portrait.q_u == q.portrait.q_u);
  EXPECT_TRUE(p.portrait.qdot_u == q.portrait.qdot_u);
  EXPECT_TRUE(p.portrait.nearest_irf == q.portrait.nearest_irf);
  EXPECT_TRUE(p.portrait.support == q.portrait.support);
  EXPECT_EQ(p.portrait.irf_start, q.portrait.irf_start);
  EXPECT_EQ(p.attributes.beta, q.attributes.beta);
}

// SIGKILL mid-run (after the first checkpoint), then --resume: the orbits equal an uninterrupted run's.
TEST(PipelineCli, SigkilledRunResumesWithNoLostOrDuplicatedOrbit) {
  const auto dir = scratch_dir("cli_sigkill");
  const std::string killed = (dir / "killed.h5").string(), straight = (dir / "straight.h5").string();
  const std::vector<std::string> opts = {"--chains", "2", "--irfs-per-chain", "12",
                                         "-j",       "1", "--max-rank",       "20"};
  const pid_t pid = testing::spawn_quietly(args(
      {testing::tool_path("phasecast-precompute").string(), "run", tiny_scene_path().string(), "-o", killed},
      opts));
  const auto first_checkpoint = std::filesystem::path(killed + ".work") / "chain-000.state.h5";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!std::filesystem::exists(first_checkpoint) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the run ended before it could be killed";
  EXPECT_FALSE(std::filesystem::exists(killed));
  const auto resumed = run_tool("phasecast-precompute",
                                args({"run", tiny_scene_path().string(), "-o", killed, "--resume"}, opts));
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  ASSERT_EQ(run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", straight}, opts))
                .exit_code,
            0);
  const auto a = precompute::read_orbit_store(straight + ".work/orbits.h5");
  const auto b = precompute::read_orbit_store(killed + ".work/orbits.h5");
  ASSERT_EQ(a.irf_start.size(), 24u);
  EXPECT_EQ(a.irf_palette, b.irf_palette);
  EXPECT_EQ(a.irf_length, b.irf_length);
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.velocities == b.velocities);
  EXPECT_TRUE(core::read_package(straight).portrait.q_u == core::read_package(killed).portrait.q_u);
}

TEST(PipelineCli, SampleThenReduceMatchesRun) {
  const auto dir = scratch_dir("cli_stages");
  const auto scene = tiny_scene_path().string();
  const auto orbits = (dir / "orbits.h5").string(), staged = (dir / "staged.h5").string(),
             whole = (dir / "whole.h5").string();
  const auto s = run_tool("phasecast-precompute", {"sample", scene, "-o", orbits, "--chains", "2",
                                                   "--irfs-per-chain", "3", "--seed", "4"});
  ASSERT_EQ(s.exit_code, 0) << s.err;
  // The self-contact of every sampled frame, its count against a second read of the store.
  const precompute::OrbitStore store = precompute::read_orbit_store(orbits);
  const Eigen::MatrixXi triangles = store.triangles.cast<int>();
  int intersecting = 0;
  for (int f = 0; f < store.frames(); ++f) {
    intersecting += precompute::count_intersecting_pairs(store.positions.row(f).cast<double>().transpose(),
                                                         triangles) > 0;
  }
  EXPECT_NE(s.out.find(fmt::format("contact: {} of {} frames with intersecting triangle pairs", intersecting,
                                   store.frames())),
            std::string::npos)
      << s.out;
  const auto r =
      run_tool("phasecast-precompute", {"reduce", scene, orbits, "-o", staged, "--max-rank", "20"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_EQ(run_tool("phasecast-precompute", args({"run", scene, "-o", whole})).exit_code, 0);
  const auto a = core::read_package(staged), b = core::read_package(whole);
  EXPECT_TRUE(a.portrait.q_u == b.portrait.q_u);
  EXPECT_TRUE(a.reduction.U_u == b.reduction.U_u);
}

TEST(PipelineCli, MissingOrbitStoreIsOneLine) {
  const auto dir = scratch_dir("cli_missing");
  const auto missing = (dir / "nope.h5").string();
  const auto r = run_tool("phasecast-precompute",
                          {"reduce", tiny_scene_path().string(), missing, "-o", (dir / "p.h5").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "phasecast-precompute: " + missing + ": no such file\n");
}

TEST(PipelineCli, BadRuleInSceneIsOneLine) {
  const auto dir = scratch_dir("cli_bad_rule");
  const auto scene = testing::edited_tiny_scene(dir, "on_end = \"rest\"", "on_end = \"halt\"").string();
  const auto r = run_tool("phasecast-precompute", args({"run", scene, "-o", (dir / "p.h5").string()}));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(one_line(r.err)) << r.err;
  EXPECT_NE(r.err.find("field 'on_end': unknown name 'halt'"), std::string::npos) << r.err;
  // simulate reads the same rules, with the same line.
  const auto sim = run_tool("phasecast-precompute",
                            {"simulate", scene, "--schedule", "open 0.1", "-o", (dir / "sim.h5").string()});
  EXPECT_EQ(sim.exit_code, 1);
  EXPECT_NE(sim.err.find("field 'on_end': unknown name 'halt' (expected rest, hold, close, stop, open)"),
            std::string::npos)
      << sim.err;
}

TEST(PipelineCli, BadNumbersAreOneLine) {
  const auto dir = scratch_dir("cli_bad_numbers");
  const auto scene = tiny_scene_path().string();
  const auto orbits = (dir / "orbits.h5").string(), pkg = (dir / "p.h5").string();
  ASSERT_EQ(run_tool("phasecast-precompute",
                     {"sample", scene, "-o", orbits, "--chains", "1", "--irfs-per-chain", "1"})
                .exit_code,
            0);
  const auto eps = run_tool("phasecast-precompute", {"reduce", scene, orbits, "-o", pkg, "--eps-u", "nan"});
  EXPECT_EQ(eps.exit_code, 1);
  EXPECT_TRUE(one_line(eps.err)) << eps.err;
  EXPECT_NE(eps.err.find("--eps-u in [0, 1), got 0, 60, nan"), std::string::npos) << eps.err;
  const auto lambda = run_tool("phasecast-precompute", {"reduce", scene, orbits, "-o", pkg, "--max-rank", "5",
                                                        "--blend-lambda", "-1"});
  EXPECT_EQ(lambda.exit_code, 1);
  EXPECT_TRUE(one_line(lambda.err)) << lambda.err;
  EXPECT_NE(lambda.err.find("--blend-lambda > 0"), std::string::npos) << lambda.err;
  EXPECT_NE(lambda.err.find("got 0, -1, 0.1, 3"), std::string::npos) << lambda.err;
  const auto chains = run_tool("phasecast-precompute", {"sample", scene, "-o", orbits, "--chains", "0"});
  EXPECT_EQ(chains.exit_code, 1);
  EXPECT_TRUE(one_line(chains.err)) << chains.err;
  EXPECT_NE(chains.err.find("expected chains, IRFs per chain and jobs >= 1, got 0, 16, 2"), std::string::npos)
      << chains.err;
}

TEST(PipelineCli, HelpListsTheSubcommands) {
  const auto r = run_tool("phasecast-precompute", {"--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* cmd : {"sample", "reduce", "run"}) EXPECT_NE(r.out.find(cmd), std::string::npos) << cmd;
}

}  // namespace
}  // namespace phasecast
