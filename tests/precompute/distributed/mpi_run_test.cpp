// phasecast-precompute run under a real mpirun (Open MPI, ranks on this
// machine): the package of any number of ranks is the single process's, bit
// for bit, dataset by dataset and as a file, and so are the transfers it saves; a rank killed mid-run loses
// no finished chain and --resume finishes the same package; a rank that fails ends every rank with one line
// naming it.

#include "fresh_schedule_run.h"
#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/package.h"
#include "phasecast/precompute/appearance/transfer_file.h"
#include "run_tool.h"
#include "same_package.h"
#include "scene_files.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <dirent.h>
#include <signal.h>
#include <sys/wait.h>
#include <chrono>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

namespace phasecast {
namespace {

using testing::expect_same_package;
using testing::read_file;
using testing::run_command;
using testing::scratch_dir;
using testing::tiny_scene_path;

// A sample this thin may leave an entry without IRFs, which run would refuse (not what these tests are
// about).
const std::vector<std::string> kSmall = {"--chains",
                                         "3",
                                         "--seed",
                                         "4",
                                         "-j",
                                         "1",
                                         "--max-rank",
                                         "20",
                                         "--clusters",
                                         "5",
                                         "--allow-missing-entries"};

// mpirun (root allowed: CI runs as root) with `launch` before the tool and
// its arguments, e.g. {"-np", "3"}; at most three minutes.
std::vector<std::string> mpirun_argv(const std::vector<std::string>& launch) {
  std::vector<std::string> argv{"timeout", "180", PHASECAST_MPIEXEC, "--oversubscribe",
                                "--allow-run-as-root"};
  argv.insert(argv.end(), launch.begin(), launch.end());
  return argv;
}

std::vector<std::string> precompute_run(const std::filesystem::path& out, std::vector<std::string> extra = {},
                                        const std::string& irfs_per_chain = "2") {
  std::vector<std::string> a{testing::tool_path("phasecast-precompute").string(),
                             "run",
                             tiny_scene_path().string(),
                             "-o",
                             out.string(),
                             "--irfs-per-chain",
                             irfs_per_chain};
  a.insert(a.end(), kSmall.begin(), kSmall.end());
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

std::vector<std::string> concat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// The single-process package, the truth every run is compared with.
core::ScenePackage single_process(const std::filesystem::path& dir, std::string* out = nullptr) {
  const auto r = run_command(precompute_run(dir / "np1.h5"));
  if (r.exit_code != 0) throw std::runtime_error("single-process run failed: " + r.err);
  if (out) *out = r.out;
  return core::read_package(dir / "np1.h5");
}

// The "contact: ..." line a run printed for its sampled frames.
std::string contact_line(const std::string& out) {
  const auto at = out.find("contact: ");
  return at == std::string::npos ? std::string() : out.substr(at, out.find('\n', at) - at);
}

TEST(MpiRun, AnyNumberOfRanksWritesTheSinglePackage) {
  const auto dir = scratch_dir("mpi_any_n");
  std::string truth_out;
  const auto truth = single_process(dir, &truth_out);
  ASSERT_NE(contact_line(truth_out), "") << truth_out;
  for (const char* n : {"2", "3"}) {
    const auto pkg = dir / (std::string("np") + n + ".h5");
    const auto r = run_command(concat(mpirun_argv({"-np", n}), precompute_run(pkg)));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find(std::string(", ") + n + " MPI ranks"), std::string::npos) << r.err;
    EXPECT_NE(r.out.find("wrote " + pkg.string() + ": N = "), std::string::npos) << r.out;
    // Each rank checks its own chains' frames; the combined count is the single process's.
    EXPECT_EQ(contact_line(r.out), contact_line(truth_out));
    SCOPED_TRACE(std::string("np ") + n);
    expect_same_package(truth, core::read_package(pkg));
    // The file itself too: packages carry no times, so same content is same bytes (same hash).
    EXPECT_TRUE(read_file(pkg) == read_file(dir / "np1.h5")) << "np " << n << ": the files differ";
  }
}

// --until-fidelity under mpirun: every rank reduces and validates alike, the
// directed chains of each round (up to --chains of them with
// --directed-chains 0) spread over the ranks, and the package is the single
// process's, bit for bit.
TEST(MpiRun, AdaptiveSamplingWritesTheSinglePackage) {
  const auto dir = scratch_dir("mpi_adaptive");
  const std::vector<std::string> adaptive = {
      "--no-appearance",   "--no-check", "--until-fidelity",     "0.001", "--budget-irfs",     "10",
      "--guide-schedules", "3",          "--held-out-schedules", "2",     "--directed-chains", "0"};
  const auto single = run_command(precompute_run(dir / "np1.h5", adaptive));
  ASSERT_EQ(single.exit_code, 0) << single.err;
  ASSERT_NE(single.err.find("adaptive round 1: "), std::string::npos) << "one round only: " << single.err;
  const auto two = run_command(concat(mpirun_argv({"-np", "2"}), precompute_run(dir / "np2.h5", adaptive)));
  ASSERT_EQ(two.exit_code, 0) << two.err;
  EXPECT_TRUE(read_file(dir / "np2.h5") == read_file(dir / "np1.h5")) << "the files differ";
}

// Fresh schedules under mpirun: on the tiny toy (seed 5, one guide schedule)
// round 1 meets the target on its guide, the fresh ones miss it and join the
// guides, and round 2's chain is aimed at them (PipelineCli's
// UntilFidelityChecksMetGuideFiguresOnFreshSchedules); two ranks draw and
// judge alike, to the single process's bytes.
TEST(MpiRun, FreshScheduleRoundsWriteTheSinglePackage) {
  const auto dir = scratch_dir("mpi_fresh");
  const auto run = [&dir](const std::string& name) {
    std::vector<std::string> argv{testing::tool_path("phasecast-precompute").string(), "run",
                                  testing::fresh_schedule_scene(), "-o", (dir / name).string()};
    const auto options = testing::fresh_schedule_options("4", "0");
    argv.insert(argv.end(), options.begin(), options.end());
    return argv;
  };
  const auto single = run_command(run("np1.h5"));
  ASSERT_EQ(single.exit_code, 0) << single.err;
  ASSERT_NE(single.out.find("on 4 fresh ones after 3 rounds"), std::string::npos) << single.out;
  const auto two = run_command(concat(mpirun_argv({"-np", "2"}), run("np2.h5")));
  ASSERT_EQ(two.exit_code, 0) << two.err;
  EXPECT_TRUE(read_file(dir / "np2.h5") == read_file(dir / "np1.h5")) << "the files differ";
}

// --save-transfers under mpirun: each rank casts its share of the transfers,
// all of them hold every row after the exchange, and one writes the file,
// which holds what the single process's does, bit for bit.
TEST(MpiRun, SavedTransfersAreTheSingleProcesss) {
  const auto dir = scratch_dir("mpi_save_transfers");
  const auto one =
      run_command(precompute_run(dir / "np1.h5", {"--save-transfers", (dir / "np1.t.h5").string()}));
  ASSERT_EQ(one.exit_code, 0) << one.err;
  const auto three =
      run_command(concat(mpirun_argv({"-np", "3"}),
                         precompute_run(dir / "np3.h5", {"--save-transfers", (dir / "np3.t.h5").string()})));
  ASSERT_EQ(three.exit_code, 0) << three.err;
  const std::string wrote = "appearance: wrote " + (dir / "np3.t.h5").string();
  const auto first = three.err.find(wrote);
  ASSERT_NE(first, std::string::npos) << three.err;
  EXPECT_EQ(three.err.find(wrote, first + 1), std::string::npos) << "written by more than one rank";
  const auto truth = precompute::read_stage_transfers(dir / "np1.t.h5");
  const auto ranks = precompute::read_stage_transfers(dir / "np3.t.h5");
  EXPECT_GT(truth.fields.rows(), 5);  // the 5 representatives and held-out nodes
  EXPECT_TRUE(ranks.fields == truth.fields);
  EXPECT_EQ(ranks.nodes, truth.nodes);
  EXPECT_EQ(ranks.roles, truth.roles);
  EXPECT_EQ(ranks.labels, truth.labels);
  EXPECT_TRUE(ranks.q_u == truth.q_u);
}

// The ranks mpirun started (its children running phasecast-precompute).
std::vector<pid_t> ranks_of(pid_t mpirun) {
  std::vector<pid_t> found;
  DIR* proc = ::opendir("/proc");
  while (const dirent* e = proc ? ::readdir(proc) : nullptr) {
    const pid_t pid = static_cast<pid_t>(std::atoi(e->d_name));
    if (pid <= 0) continue;
    std::ifstream stat(std::string("/proc/") + e->d_name + "/stat");
    std::string line;
    std::getline(stat, line);
    const auto close = line.rfind(')');
    if (close == std::string::npos || line.find("(phasecast-prec") == std::string::npos) continue;
    std::istringstream rest(line.substr(close + 2));
    char state = 0;
    pid_t parent = 0;
    rest >> state >> parent;
    if (parent == mpirun) found.push_back(pid);
  }
  if (proc) ::closedir(proc);
  return found;
}

// IRFs chain k's state checkpoint says are finished (0 without one).
int checkpointed_irfs(const std::filesystem::path& work, int chain) {
  const auto path = work / fmt::format("chain-{:03d}.state.h5", chain);
  if (!std::filesystem::exists(path)) return 0;
  return static_cast<int>(core::h5::File::open_read(path).read_attribute_number("irfs"));
}

// IRFs the chains of a run report sampling ("chain k: n IRFs, ..." lines).
int sampled_irfs(const std::string& err) {
  static const std::regex line(R"(chain \d+: (\d+) IRFs, )");
  int n = 0;
  for (std::sregex_iterator it(err.begin(), err.end(), line), end; it != end; ++it) n += std::stoi((*it)[1]);
  return n;
}

TEST(MpiRun, KilledRankLosesNoFinishedChainAndResumeWritesTheSamePackage) {
  const auto dir = scratch_dir("mpi_killed");
  const auto truth_run = run_command(precompute_run(dir / "np1.h5", {}, "8"));
  ASSERT_EQ(truth_run.exit_code, 0) << truth_run.err;
  const auto truth = core::read_package(dir / "np1.h5");

  const auto pkg = dir / "killed.h5";
  const pid_t mpirun =
      testing::spawn_quietly(concat({PHASECAST_MPIEXEC, "--oversubscribe", "--allow-run-as-root", "-np", "3"},
                                    precompute_run(pkg, {}, "8")));
  // Once chain 1 (rank 1) has checkpointed an IRF, kill rank 1's process.
  const auto checkpoint = dir / "killed.h5.work" / "chain-001.state.h5";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!std::filesystem::exists(checkpoint) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  const auto ranks = ranks_of(mpirun);
  ASSERT_EQ(ranks.size(), 3u);
  ::kill(ranks[1], SIGKILL);
  int status = 0;
  ::waitpid(mpirun, &status, 0);
  ASSERT_FALSE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the run ended before a rank was killed";
  EXPECT_FALSE(std::filesystem::exists(pkg));
  // What the checkpoints hold after the kill: the resume must sample exactly the rest.
  int checkpointed = 0;
  for (int k = 0; k < 3; ++k) checkpointed += checkpointed_irfs(dir / "killed.h5.work", k);
  ASSERT_GE(checkpointed, 1) << "no finished IRF survived the kill";

  const auto resumed = run_command(concat(mpirun_argv({"-np", "3"}), precompute_run(pkg, {"--resume"}, "8")));
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("(resuming)"), std::string::npos) << resumed.err;
  EXPECT_EQ(sampled_irfs(resumed.err), 3 * 8 - checkpointed) << resumed.err;
  expect_same_package(truth, core::read_package(pkg));
  EXPECT_TRUE(read_file(pkg) == read_file(dir / "np1.h5")) << "the resumed package's file differs";
}

TEST(MpiRun, ABadOptionOnOneRankEndsEveryRankWithOneLine) {
  const auto dir = scratch_dir("mpi_bad_option");
  // Two ranks with good options and one (rank 2) whose option is not a number.
  const auto r = run_command(
      concat(concat(mpirun_argv({"-np", "2"}), precompute_run(dir / "bad.h5")),
             concat({":", "-np", "1"}, precompute_run(dir / "bad.h5", {"--cluster-seed", "many"}))));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, 124) << "the ranks did not stop within 180 s";
  EXPECT_NE(r.err.find(
                "phasecast-precompute: rank 2 of 3: Could not convert: --cluster-seed = many (see --help)\n"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.h5"));
}

TEST(MpiRun, AFailingRankNamesItselfAndEndsTheRun) {
  const auto dir = scratch_dir("mpi_failing_rank");
  // Ranks 1 and 2 are given a scene file that does not exist.
  const auto missing = dir / "no_such_scene.toml";
  auto bad = precompute_run(dir / "fail.h5");
  bad[2] = missing.string();
  const auto r = run_command(concat(concat(mpirun_argv({"-np", "1"}), precompute_run(dir / "fail.h5")),
                                    concat({":", "-np", "2"}, bad)));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, 124) << "the ranks did not stop within 180 s";
  // Either failing rank may be the first to print and end the others.
  EXPECT_TRUE(r.err.find("phasecast-precompute: rank 1 of 3: ") != std::string::npos ||
              r.err.find("phasecast-precompute: rank 2 of 3: ") != std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(missing.string()), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "fail.h5"));
}

// Commands that do not share their work refuse to run on several ranks
// (each rank would do all of it and write the same output).
TEST(MpiRun, OneProcessCommandsRefuseSeveralRanks) {
  const auto dir = scratch_dir("mpi_one_process");
  const auto r =
      run_command(concat(mpirun_argv({"-np", "2"}), {testing::tool_path("phasecast-precompute").string(),
                                                     "simulate", tiny_scene_path().string(), "--schedule",
                                                     "open 0.1", "-o", (dir / "orbit.h5").string()}));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("of 2: simulate runs in one process: start it without mpirun"), std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "orbit.h5"));
}

// One of several tasks of a Slurm step that no MPI launcher connected (srun
// without --mpi=pmix) refuses rather than run the whole job beside the others.
TEST(MpiRun, AnUnconnectedSlurmTaskRefuses) {
  const auto dir = scratch_dir("mpi_slurm_unwired");
  auto argv = precompute_run(dir / "pkg.h5");
  argv.insert(argv.begin(), {"env", "SLURM_STEP_NUM_TASKS=4"});
  const auto r = run_command(argv);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("one of 4 tasks of a Slurm step, but no MPI launcher connected them"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "pkg.h5.work"));
}

}  // namespace
}  // namespace phasecast
