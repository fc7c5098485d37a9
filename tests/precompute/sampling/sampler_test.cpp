// IRF sampling: rules obeyed in the recorded orbits, determinism, and resume
// after an interrupted run giving bit-identical orbits.

#include "phasecast/precompute/sampling/irf_sampler.h"
#include "run_tool.h"
#include "scene_files.h"
#include "source_tree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <mutex>
#include <numbers>
#include <vector>

namespace phasecast::precompute {
namespace {

using testing::scratch_dir;
using testing::tiny_scene_path;

SamplingOptions small_options(const std::filesystem::path& dir) {
  SamplingOptions o;
  o.chains = 2;
  o.irfs_per_chain = 4;
  o.seed = 11;
  o.jobs = 2;
  o.work_dir = dir;
  return o;
}

void expect_identical(const OrbitStore& a, const OrbitStore& b) {
  EXPECT_EQ(a.irf_start, b.irf_start);
  EXPECT_EQ(a.irf_length, b.irf_length);
  EXPECT_EQ(a.irf_palette, b.irf_palette);
  EXPECT_EQ(a.frame_palette, b.frame_palette);
  ASSERT_EQ(a.positions.rows(), b.positions.rows());
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.velocities == b.velocities);
  EXPECT_TRUE(a.support == b.support);
}

class Sampler : public ::testing::Test {
 protected:
  Scene scene = load_scene_file(tiny_scene_path());
  PaletteRules rules = make_palette_rules(scene);
};

// The door's opening angle at frame f, from the recorded 3x4 support transform
// (a rotation about the vertical hinge): acos((trace R - 1) / 2).
double door_angle(const OrbitStore& s, int f) {
  const double trace = s.support(f, 0) + s.support(f, 5) + s.support(f, 10);
  return std::acos(std::clamp((trace - 1) / 2, -1.0, 1.0));
}

// A directed chain's first two IRFs are the lead-in's last two items, the
// segment's continuing the one before it, recorded from the state the items
// before them (simulated, not recorded) left: bit for bit the frames the
// schedule's own simulation shows in those segments. Only the first recorded
// start counts as still. A resumed directed chain is the same.
TEST_F(Sampler, ADirectedChainStartsWhereItsScheduleStood) {
  const std::vector<ScheduleItem> lead_in = parse_schedule("open 0.4; stop 0.3; close 0.2", scene);
  SamplingOptions o = small_options(scratch_dir("sampler_directed"));
  o.chains = 2;
  o.irfs_per_chain = 3;
  o.lead_ins = {lead_in};  // chain 1 has none: it starts at rest
  const OrbitStore s = sample_irfs(scene, rules, o);
  const OrbitStore truth = simulate_schedule(scene, lead_in);
  int recorded = 0;
  for (int item = 1; item <= 2; ++item) {
    const auto k = static_cast<size_t>(item - 1);
    const auto i = static_cast<size_t>(item);
    ASSERT_EQ(s.irf_palette[k], lead_in[i].entry) << "IRF " << k;
    const int frames = schedule_frames(lead_in[i].duration, scene.simulation.frame_dt);
    ASSERT_EQ(s.irf_length[k], frames);
    ASSERT_EQ(truth.irf_length[i], frames);
    EXPECT_TRUE(s.positions.middleRows(recorded, frames) ==
                truth.positions.middleRows(truth.irf_start[i], frames));
    EXPECT_TRUE(s.support.middleRows(recorded, frames) ==
                truth.support.middleRows(truth.irf_start[i], frames));
    recorded += frames;
  }
  EXPECT_EQ(s.irf_continues[0], 0) << "the first recorded start counts as still";
  EXPECT_EQ(s.irf_continues[1], 1) << "the segment's IRF continues the one before it";
  EXPECT_EQ(s.irf_palette.size(), 6u);  // 3 IRFs a chain, the lead-in's two recorded ones counted
  // Stopped after its first IRF and resumed: the same orbits.
  SamplingOptions stopped = o;
  stopped.work_dir = scratch_dir("sampler_directed_resumed");
  stopped.jobs = 1;
  stopped.stop_after_irfs = 1;
  EXPECT_THROW(sample_irfs(scene, rules, stopped), SamplingError);
  stopped.stop_after_irfs = 0;
  stopped.resume = true;
  expect_identical(sample_irfs(scene, rules, stopped), s);
}

// A directed chain too short to record its segment's IRF is refused.
TEST_F(Sampler, ADirectedChainShorterThanItsRecordedLeadInIsRefused) {
  SamplingOptions o = small_options(scratch_dir("sampler_directed_short"));
  o.chains = 1;
  o.irfs_per_chain = 1;
  o.lead_ins = {parse_schedule("open 0.4; stop 0.3; close 0.2", scene)};
  try {
    sample_irfs(scene, rules, o);
    FAIL() << "expected a SamplingError";
  } catch (const SamplingError& e) {
    EXPECT_STREQ(e.what(), "sampling: chain 0's lead-in records 2 IRFs, expected IRFs per chain >= 2, got 1");
  }
  o.lead_ins = {parse_schedule("open 0.4", scene)};  // a schedule's first segment: recorded alone
  EXPECT_EQ(sample_irfs(scene, rules, o).irf_palette.size(), 1u);
}

// An adaptive round's chain k is aimed at the segment the options before the
// round pick: resumed with another lead-in (say another --directed-chains),
// its checkpoint is another chain's and is sampled again, never continued.
TEST_F(Sampler, ACheckpointOfAnotherLeadInIsSampledAgain) {
  SamplingOptions o = small_options(scratch_dir("sampler_directed_other_lead_in"));
  o.chains = 1;
  o.irfs_per_chain = 3;
  o.jobs = 1;
  o.lead_ins = {parse_schedule("open 0.4; stop 0.3; close 0.2", scene)};
  o.stop_after_irfs = 2;
  EXPECT_THROW(sample_irfs(scene, rules, o), SamplingError);
  std::vector<std::string> notices;
  o.notice = [&notices](const std::string& line) { notices.push_back(line); };
  o.stop_after_irfs = 0;
  o.resume = true;
  o.lead_ins = {parse_schedule("open 0.6; stop 0.2", scene)};
  const OrbitStore resumed = sample_irfs(scene, rules, o);
  ASSERT_EQ(notices.size(), 1u);
  EXPECT_NE(notices[0].find("chain 0: its checkpoint was led in by another guide segment"), std::string::npos)
      << notices[0];
  SamplingOptions fresh = o;
  fresh.work_dir = scratch_dir("sampler_directed_other_lead_in_fresh");
  fresh.resume = false;
  expect_identical(resumed, sample_irfs(scene, rules, fresh));
}

TEST_F(Sampler, RecordedChainsObeyThePaletteRules) {
  const auto o = small_options(scratch_dir("sampler_rules"));
  const OrbitStore s = sample_irfs(scene, rules, o);
  ASSERT_EQ(s.irf_start.size(), 8u);
  validate_orbit_store(s, "sampled");
  for (int chain = 0; chain < o.chains; ++chain) {
    int previous = -1;
    for (int i = 0; i < o.irfs_per_chain; ++i) {
      const auto k = static_cast<size_t>(chain * o.irfs_per_chain + i);
      const int entry = s.irf_palette[k];
      EXPECT_TRUE(rules.allowed(previous, entry)) << "chain " << chain << " IRF " << i;
      EXPECT_GE(s.irf_length[k], 1);  // T may be clipped below t_min by the range
      EXPECT_LE(s.irf_length[k], rules.max_frames[static_cast<size_t>(entry)]);
      // §3.5, read back from the recorded support: a door-moving IRF really moves
      // the door (never drawn against its stop), and the door stays in [0, 90] degrees.
      const int first = s.irf_start[k], last = first + s.irf_length[k] - 1;
      const double swing = std::abs(door_angle(s, last) - door_angle(s, first));
      if (rules.support_rate[static_cast<size_t>(entry)] != 0 && s.irf_length[k] > 1) {
        EXPECT_GT(swing, 0.9 * 1.5 * scene.simulation.frame_dt) << "chain " << chain << " IRF " << i;
      }
      for (int f = first; f <= last; ++f) EXPECT_LE(door_angle(s, f), std::numbers::pi / 2 + 1e-3);
      previous = entry;
    }
  }
  // The cloth moves: the door swings it.
  EXPECT_GT((s.positions.rowwise() - s.positions.row(0)).rowwise().norm().maxCoeff(), 1e-3f);
}

TEST_F(Sampler, SameSeedGivesBitIdenticalOrbitsWhateverTheJobCount) {
  auto o = small_options(scratch_dir("sampler_det_a"));
  const OrbitStore a = sample_irfs(scene, rules, o);
  o.work_dir = scratch_dir("sampler_det_b");
  o.jobs = 1;
  const OrbitStore b = sample_irfs(scene, rules, o);
  expect_identical(a, b);
}

// CHOLMOD's supernodal factorization calls a BLAS that two threads may not
// enter together: chains sampled at once got a garbage factor ("not positive
// definite" at their first step) until they took turns. The default cloth is
// the smallest shipped scene whose supernodes are large enough to reach BLAS.
TEST(SamplerSupernodal, ChainsAtOnceMatchChainsOneAfterAnother) {
  Scene scene = load_scene_file(phasecast::testing::scenes_dir() / "cloth_door.toml");
  scene.simulation.linear_solver = LinearSolver::supernodal;
  const PaletteRules rules = make_palette_rules(scene);
  SamplingOptions o;
  o.chains = 2;
  o.irfs_per_chain = 1;
  o.seed = 3;
  o.jobs = 2;
  o.work_dir = scratch_dir("sampler_supernodal_a");
  const OrbitStore together = sample_irfs(scene, rules, o);
  o.jobs = 1;
  o.work_dir = scratch_dir("sampler_supernodal_b");
  expect_identical(together, sample_irfs(scene, rules, o));
}

TEST_F(Sampler, ResumeAfterAStoppedRunLosesAndDuplicatesNothing) {
  const auto dir = scratch_dir("sampler_resume");
  auto o = small_options(dir);
  o.jobs = 1;
  o.stop_after_irfs = 3;
  try {
    sample_irfs(scene, rules, o);
    FAIL() << "expected the run to stop";
  } catch (const SamplingError& e) {
    EXPECT_NE(std::string(e.what()).find("stopped after 3 new IRFs (--stop-after-irfs); rerun with --resume"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(read_orbit_store(dir / "chain-000.h5").irf_start.size(), 3u);
  o.stop_after_irfs = 0;
  o.resume = true;
  const OrbitStore resumed = sample_irfs(scene, rules, o);
  const OrbitStore straight = sample_irfs(scene, rules, small_options(scratch_dir("sampler_straight")));
  expect_identical(resumed, straight);
}

// Each chain reports the IRFs and state nodes it sampled (the per-chain
// figures of docs/distributed.md): the store's own counts, and on a resume only
// what the resumed run added.
TEST_F(Sampler, EveryChainReportsWhatItSampledAndAResumeOnlyWhatItAdded) {
  const auto dir = scratch_dir("sampler_chain_reports");
  auto o = small_options(dir);
  o.jobs = 1;
  o.stop_after_irfs = 3;  // chain 0 stops after 3 of its 4 IRFs, chain 1 does not start
  std::mutex mutex;
  std::vector<ChainSampled> reports;
  o.chain_sampled = [&](const ChainSampled& c) {
    std::lock_guard lock(mutex);
    reports.push_back(c);
  };
  EXPECT_THROW(sample_irfs(scene, rules, o), SamplingError);
  EXPECT_TRUE(reports.empty()) << "a chain that stopped short reported itself done";
  o.stop_after_irfs = 0;
  o.resume = true;
  const OrbitStore all = sample_irfs(scene, rules, o);
  ASSERT_EQ(reports.size(), 2u);
  std::sort(reports.begin(), reports.end(), [](auto& a, auto& b) { return a.chain < b.chain; });
  const auto frames_of = [&](int first_irf, int irfs) {
    long long n = 0;
    for (int i = first_irf; i < first_irf + irfs; ++i) n += all.irf_length[static_cast<size_t>(i)];
    return n;
  };
  EXPECT_EQ(reports[0].irfs, 1);  // the resumed chain: its 4th IRF only
  EXPECT_EQ(reports[0].frames, frames_of(3, 1));
  EXPECT_EQ(reports[1].irfs, 4);
  EXPECT_EQ(reports[1].frames, frames_of(4, 4));
  for (const auto& c : reports) {
    EXPECT_GT(c.settle_seconds, 0) << "chain " << c.chain;
    EXPECT_GT(c.seconds, c.settle_seconds) << "chain " << c.chain;
  }
}

TEST_F(Sampler, ResumeDropsAnIrfWrittenAfterTheLastStateCheckpoint) {
  const auto dir = scratch_dir("sampler_torn");
  auto o = small_options(dir);
  o.chains = 1;
  o.stop_after_irfs = 2;
  EXPECT_THROW(sample_irfs(scene, rules, o), SamplingError);
  // Simulate a crash between the store and the state write: the store holds one more IRF.
  OrbitStore torn = read_orbit_store(dir / "chain-000.h5");
  const auto extra_start = static_cast<std::int32_t>(torn.frames());
  torn.irf_start.push_back(extra_start);
  torn.irf_length.push_back(1);
  torn.irf_palette.push_back(1);
  torn.irf_continues.push_back(1);
  torn.frame_palette.push_back(1);
  torn.positions.conservativeResize(torn.frames() + 1, Eigen::NoChange);
  torn.positions.bottomRows(1).setZero();
  torn.velocities.conservativeResize(torn.positions.rows(), Eigen::NoChange);
  torn.velocities.bottomRows(1).setZero();
  torn.support.conservativeResize(torn.positions.rows(), Eigen::NoChange);
  torn.support.bottomRows(1).setZero();
  write_orbit_store(torn, dir / "chain-000.h5");
  o.stop_after_irfs = 0;
  o.resume = true;
  const OrbitStore resumed = sample_irfs(scene, rules, o);
  auto straight_options = small_options(scratch_dir("sampler_torn_straight"));
  straight_options.chains = 1;
  expect_identical(resumed, sample_irfs(scene, rules, straight_options));
}

TEST_F(Sampler, ResumeWithAnotherSeedIsRejected) {
  const auto dir = scratch_dir("sampler_seed");
  auto o = small_options(dir);
  o.chains = 1;
  o.stop_after_irfs = 1;
  EXPECT_THROW(sample_irfs(scene, rules, o), SamplingError);
  o.stop_after_irfs = 0;
  o.resume = true;
  o.seed = 12;
  try {
    sample_irfs(scene, rules, o);
    FAIL() << "expected a SamplingError";
  } catch (const SamplingError& e) {
    EXPECT_NE(std::string(e.what()).find("checkpoint of seed 11 chain 0, expected seed 12 chain 0"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(Sampler, ResumeWithFewerIrfsThanCheckpointedIsRejected) {
  const auto dir = scratch_dir("sampler_fewer");
  auto o = small_options(dir);
  o.chains = 1;
  o.irfs_per_chain = 2;
  sample_irfs(scene, rules, o);
  o.irfs_per_chain = 1;
  o.resume = true;
  try {
    sample_irfs(scene, rules, o);
    FAIL() << "expected a SamplingError";
  } catch (const SamplingError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "chain-000.state.h5: checkpoint holds 2 IRFs, more than --irfs-per-chain 1"),
              std::string::npos)
        << e.what();
  }
}

// Two ranks sharing a work folder, in turn: rank 0's chains alone cannot be
// merged (one line names the missing chain); with rank 1's they give the
// single process's orbits.
TEST_F(Sampler, RanksSharingAWorkFolderMergeToTheSingleProcessOrbits) {
  auto o = small_options(scratch_dir("sampler_ranks"));
  o.ranks = 2;
  sample_own_chains(scene, rules, o);
  try {
    read_chain_stores(scene, o);
    FAIL() << "expected a SamplingError";
  } catch (const SamplingError& e) {
    EXPECT_EQ(std::string(e.what()), (o.work_dir / "chain-001.h5").string() +
                                         ": chain 1 has no store (expected every rank to share the work "
                                         "folder; docs/distributed.md)");
  }
  o.rank = 1;
  sample_own_chains(scene, rules, o);
  expect_identical(read_chain_stores(scene, o),
                   sample_irfs(scene, rules, small_options(scratch_dir("sampler_one"))));
}

TEST_F(Sampler, WorkFolderThatIsAFileIsRejected) {
  const auto dir = scratch_dir("sampler_work_file");
  std::ofstream(dir / "file") << "x";
  auto o = small_options(dir / "file");
  try {
    sample_irfs(scene, rules, o);
    FAIL() << "expected a SamplingError";
  } catch (const SamplingError& e) {
    EXPECT_NE(std::string(e.what()).find("work folder " + (dir / "file").string() + ": cannot create it"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(Sampler, BadOptionsAreRejected) {
  auto o = small_options(scratch_dir("sampler_bad"));
  o.chains = 0;
  try {
    sample_irfs(scene, rules, o);
    FAIL() << "expected a SamplingError";
  } catch (const SamplingError& e) {
    EXPECT_NE(std::string(e.what()).find("expected chains, IRFs per chain and jobs >= 1, got 0, 4, 2"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace phasecast::precompute
