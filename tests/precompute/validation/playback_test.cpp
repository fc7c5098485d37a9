// The validator on the committed tiny packages (tests/data/packages, sampled
// by scripts/regen-test-data): bounds derived from measurement, with margin
// (docs/validation.md), and checks that each figure can fail.

#include "phasecast/precompute/validation/playback.h"
#include "error_of.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/server/synthesis_engine.h"
#include "run_tool.h"
#include "scene_files.h"
#include "source_tree.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>

namespace phasecast::precompute {
namespace {

const std::filesystem::path kScene = phasecast::testing::scenes_dir() / "tiny/cloth_door.toml";
const std::filesystem::path kPackage = phasecast::testing::source_dir() / "tests/data/packages/cloth_door.h5";
constexpr const char* kStandard = "open 0.8; stop 1.5; close 0.8; stop 1.5";

std::shared_ptr<const core::ScenePackage> package() {
  static const auto p = std::make_shared<const core::ScenePackage>(core::read_package(kPackage));
  return p;
}

const Scene& scene() {
  static const Scene s = load_scene_file(kScene);
  return s;
}

// Measured 2026-11-22 on this package: NRMSE 0.32, motion ratio 0.85, no
// refusals, no self-intersections (vacuous here: the tiny cloth never comes
// near itself). Before the sampler and server fixes the default package gave
// NRMSE 0.82 and moved 4 % as much as the simulation while the door opened.
TEST(Playback, TheStandardDoorScheduleFollowsTheSimulation) {
  const auto g = validate_schedule(scene(), package(), parse_schedule(kStandard, scene()));
  EXPECT_LT(g.nrmse, 0.5);
  EXPECT_GT(g.motion_ratio, 0.67);
  EXPECT_LT(g.motion_ratio, 1.5);
  ASSERT_EQ(g.segments.size(), 4u);
  for (const auto& s : g.segments) EXPECT_EQ(s.refused, "") << s.entry;
  // The closing door throws the cloth off the board: that segment must move as the simulation does.
  EXPECT_GT(g.segments[2].motion_ratio, 0.67);
  EXPECT_LT(g.segments[2].motion_ratio, 1.5);
  EXPECT_EQ(g.max_intersecting_pairs, 0);
  EXPECT_FALSE(g.switches.empty());
}

// A scene's standard schedule on another committed tiny package.
ScheduleFigures standard_figures(const std::string& name) {
  const Scene scene = load_scene_file(phasecast::testing::scenes_dir() / ("tiny/" + name + ".toml"));
  const auto pkg = std::make_shared<const core::ScenePackage>(
      core::read_package(phasecast::testing::source_dir() / "tests/data/packages" / (name + ".h5")));
  ValidationOptions o;
  o.intersections = false;
  return validate_schedule(scene, pkg, parse_schedule(scene.standard_schedule, scene), o);
}

// Measured 2026-11-23 with jolts drawn to rest (t_min 0.6 s): NRMSE 0.008,
// motion ratio 1.00, every segment's ratio in [0.997, 1.008], 4 of 4 switches
// within 2x the local motion (jolts of 0.1-1 s: NRMSE 0.087).
TEST(Playback, TheToyFollowsItsJoltsOnItsStandardSchedule) {
  const auto g = standard_figures("toy_dashboard");
  EXPECT_LT(g.nrmse, 0.05);
  EXPECT_GT(g.motion_ratio, 0.9);
  EXPECT_LT(g.motion_ratio, 1.1);
  ASSERT_EQ(g.segments.size(), 4u);
  for (const auto& s : g.segments) {
    EXPECT_EQ(s.refused, "") << s.entry;
    EXPECT_GT(s.motion_ratio, 0.8) << s.entry;
    EXPECT_LT(s.motion_ratio, 1.25) << s.entry;
  }
  int smooth = 0;
  for (const auto& w : g.switches) smooth += w.ratio() <= 2;
  EXPECT_EQ(smooth, static_cast<int>(g.switches.size()));
}

// Measured 2026-11-23: the first push follows the simulation (segment NRMSE
// 0.02, motion ratio 1.00). The IRF-end check is vacuous on this schedule: its
// stops (2.5 s, 3 s) are shorter than the stop IRFs (3.5-4 s, drawn to rest),
// so no IRF ends inside it; the random schedules of docs/validation.md measure
// it (0.006 m/s). Later segments drift: the leaves spin freely about the stem
// (docs/validation.md), which is not asserted.
TEST(Playback, ThePlantFollowsItsFirstPushAndItsStopsEndAtRest) {
  const auto g = standard_figures("plant_pot");
  ASSERT_EQ(g.segments.size(), 4u);
  EXPECT_LT(g.segments[0].nrmse, 0.2);
  EXPECT_GT(g.segments[0].motion_ratio, 0.67);
  EXPECT_LT(g.segments[0].motion_ratio, 1.5);
  for (const double v : g.irf_end_speeds) EXPECT_LT(v, 0.1 * g.median_simulated_speed);
}

// The figures are not vacuous: a package whose portrait shows the mean shape
// (all q_u zero) serves a scene that never moves, and the validator says so.
TEST(Playback, AStillPackageIsCaught) {
  auto still = std::make_shared<core::ScenePackage>(*package());
  still->portrait.q_u.setZero();
  const auto g = validate_schedule(scene(), still, parse_schedule(kStandard, scene()));
  EXPECT_LT(g.motion_ratio, 0.1);  // measured 0.05: only the eq. 12 blend offsets move
  EXPECT_GT(g.nrmse, 0.8);
}

// The committed package's simulated rows embedded into the cloth subdivided
// once (what build_package does: W x-bar, W U_u, static points at rest).
std::shared_ptr<const core::ScenePackage> subdivided_package(const Scene& embedded) {
  auto p = std::make_shared<core::ScenePackage>(*package());
  const Eigen::Index rows = 3 * embedded.model.vertices();
  const VertexEmbedding W = scene_point_embedding(embedded).weights;
  p->mesh = scene_mesh(embedded);
  const MatrixXfR mean = embed_rows(W, package()->reduction.mean_shape.head(rows));
  p->reduction.mean_shape = Eigen::Map<const VectorXf>(p->mesh.rest_positions.data(), 3 * p->mesh.points());
  for (Eigen::Index q = 0; q < W.rows(); ++q)
    if (embeds(W, q)) p->reduction.mean_shape.segment(3 * q, 3) = mean.col(0).segment(3 * q, 3);
  p->reduction.U_u = embed_rows(W, package()->reduction.U_u.topRows(rows));
  p->appearance.reset();
  p->portrait.q_a.resize(p->portrait.q_u.rows(), 0);
  return p;
}

// A package with a render mesh is measured on the render points, against the
// simulation embedded the same way: the same playback, so nearly the same
// figures as on the simulated vertices. A package of another surface is refused.
TEST(Playback, ARenderMeshIsMeasuredWhereItIsShown) {
  const Scene embedded = load_scene_file(
      testing::edited_tiny_scene(testing::scratch_dir("playback_render_mesh"), "grid = { origin",
                                 "render = { subdivide = 1 }\ngrid = { origin"));
  const auto rendered = subdivided_package(embedded);
  const auto plain = validate_schedule(scene(), package(), parse_schedule(kStandard, scene()));
  const auto g = validate_schedule(embedded, rendered, parse_schedule(kStandard, embedded));
  EXPECT_NEAR(g.nrmse, plain.nrmse, 0.1 * plain.nrmse);
  EXPECT_NEAR(g.motion_ratio, plain.motion_ratio, 0.1 * plain.motion_ratio);
  EXPECT_EQ(g.max_intersecting_pairs, 0);
  EXPECT_EQ(
      testing::error_of([&] { validate_schedule(scene(), rendered, parse_schedule(kStandard, scene())); }),
      "validate: the package's scene points are not the 48 render-surface points of scene file "
      "'cloth_door_tiny' (was the package built from another version of it?)");
}

TEST(Playback, RandomSchedulesObeyTheRulesAndTheRange) {
  const auto rules = make_palette_rules(scene());
  for (int k = 0; k < 10; ++k) {
    const auto schedule = random_schedule(rules, scene().simulation.frame_dt, 1, k, 8);
    ASSERT_FALSE(schedule.empty());
    std::vector<int> history;
    double at = 0;
    for (const auto& item : schedule) {
      EXPECT_TRUE(rules.allowed_at(history, item.entry, at)) << schedule_text(scene(), schedule);
      const int frames = schedule_frames(item.duration, scene().simulation.frame_dt);
      EXPECT_LE(frames, rules.reachable_frames(item.entry, at));
      history.push_back(item.entry);
      at = rules.advance(item.entry, at, frames);
    }
  }
  // Same seed, same schedules; another seed, others.
  EXPECT_EQ(schedule_text(scene(), random_schedule(rules, 0.02, 1, 3, 6)),
            schedule_text(scene(), random_schedule(rules, 0.02, 1, 3, 6)));
  EXPECT_NE(schedule_text(scene(), random_schedule(rules, 0.02, 1, 3, 6)),
            schedule_text(scene(), random_schedule(rules, 0.02, 2, 3, 6)));
}

// validate --random draws only what the server accepts, its stop at the
// range's end included: 300 random schedules of 8 entries per tiny scene,
// played through the real synthesis engine alone (no simulation), are refused
// nothing.
TEST(Playback, RandomSchedulesAreNeverRefusedByTheServer) {
  for (const std::string name : {"cloth_door", "plant_pot", "toy_dashboard"}) {
    const Scene s = load_scene_file(phasecast::testing::scenes_dir() / ("tiny/" + name + ".toml"));
    const auto p = std::make_shared<const core::ScenePackage>(
        core::read_package(phasecast::testing::source_dir() / ("tests/data/packages/" + name + ".h5")));
    const auto rules = make_palette_rules(s);
    int refused = 0, items = 0,
        at_range_end = 0;  // the case the server stops: a push to the end of the range
    std::string first;
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      for (int k = 0; k < 100; ++k) {
        server::SynthesisEngine engine;
        engine.add_scene(p, "refusals", 0);
        const std::uint32_t id = engine.create_instance(p->attributes.scene);
        std::uint64_t frame = 0;
        double at = 0;
        for (const auto& item : random_schedule(rules, s.simulation.frame_dt, seed, k, 8)) {
          ++items;
          const int frames = schedule_frames(item.duration, s.simulation.frame_dt);
          at = rules.advance(item.entry, at, frames);
          at_range_end += rules.support_rate[static_cast<size_t>(item.entry)] != 0 &&
                          (std::abs(at - rules.range_min) < 1e-9 || std::abs(at - rules.range_max) < 1e-9);
          try {
            engine.schedule_impulse(id, item.entry, frame);
          } catch (const server::EngineError& e) {
            if (refused++ == 0) first = e.what();
          }
          for (int f = 0; f < frames; ++f, ++frame) {
            for (const auto& r : engine.tick().refused)
              if (refused++ == 0) first = r.error;
          }
        }
      }
    }
    EXPECT_EQ(refused, 0) << name << ": " << refused << " of " << items << " refused; first: " << first;
    if (rules.range_min != rules.range_max) {
      EXPECT_GT(at_range_end, 10) << name << ": pushes reach the range end";
    }
  }
}

TEST(Playback, AForbiddenEntryIsReportedWithTheRuleItBreaks) {
  // "stop" from rest: the palette allows it only after open or close.
  const auto g = validate_schedule(scene(), package(), parse_schedule("stop 0.2; open 0.2", scene()));
  EXPECT_EQ(g.segments[0].refused,
            "instance 1 (cloth_door_tiny): 'stop' is not allowed from 'rest' (allowed: close, open)");
  EXPECT_EQ(g.segments[1].refused, "");
}

TEST(ValidationSummary, CountsMovingSegmentsAndSwitchesAgainstTheTargets) {
  ScheduleFigures g;
  g.nrmse = 0.3;
  auto seg = [](double motion, double ratio) {
    SegmentFigures s;
    s.frames = 11;
    s.simulated_motion = motion;
    s.motion_ratio = ratio;
    return s;
  };
  g.segments = {seg(1e-3, 1.0), seg(1e-3, 2.0), seg(1e-6, 0.0), seg(5e-5, 0.5)};  // still, then barely moving
  g.switches = {{1, 1e-4, 1e-4}, {5, 3e-4, 1e-4}};
  ValidationSummary s;
  s.add(g);
  g.nrmse = 0.5;
  s.add(g);
  EXPECT_EQ(s.moving, 4);  // the still segment (1e-6 m/frame) and the one under 10 % of typical are not
  EXPECT_EQ(s.moving_within, 2);
  EXPECT_EQ(s.switches, 4);
  EXPECT_EQ(s.switches_within, 2);
  EXPECT_DOUBLE_EQ(s.median_nrmse(), 0.4);
}

TEST(ValidateCli, WritesEveryFigureAsJsonAndRejectsAMissingSchedule) {
  const auto dir = testing::scratch_dir("validate_cli");
  const auto r = testing::run_tool("phasecast-precompute",
                                   {"validate", kScene.string(), kPackage.string(), "--schedule", kStandard,
                                    "--random", "2", "--seed", "3", "--json", (dir / "v.json").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("given schedules: median NRMSE"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("random schedules: median NRMSE"), std::string::npos) << r.out;
  nlohmann::json j;
  std::ifstream(dir / "v.json") >> j;
  ASSERT_EQ(j["schedules"].size(), 3u);
  EXPECT_EQ(j["schedules"][0]["schedule"], "open 0.80; stop 1.50; close 0.80; stop 1.50");
  EXPECT_EQ(j["schedules"][0]["segments"].size(), 4u);
  EXPECT_LT(j["summary_given"]["median_nrmse"].get<double>(), 0.5);

  // Without --schedule the scene's [validation] schedule plays; a scene without one is an error.
  const auto standard =
      testing::run_tool("phasecast-precompute", {"validate", kScene.string(), kPackage.string()});
  EXPECT_EQ(standard.exit_code, 0) << standard.err;
  EXPECT_NE(standard.out.find("(given): open 0.80; stop 1.50; close 0.80; stop 1.50"), std::string::npos);
  const auto bare =
      testing::edited_tiny_scene(dir, std::string("[validation]\nschedule = \"") + kStandard + "\"", "");
  const auto bad = testing::run_tool("phasecast-precompute", {"validate", bare.string(), kPackage.string()});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("has no [validation] schedule; expected --schedule"), std::string::npos) << bad.err;
  const auto other =
      testing::run_tool("phasecast-precompute",
                        {"validate", (phasecast::testing::scenes_dir() / "tiny/plant_pot.toml").string(),
                         kPackage.string(), "--schedule", "stop 0.2"});
  EXPECT_NE(other.exit_code, 0);
  EXPECT_NE(other.err.find("does not match scene file"), std::string::npos) << other.err;
}

// Several packages of one scene are measured on one simulation per schedule:
// each gets the figures it gets alone, and a package of another scene is
// refused, by its path, before anything is simulated.
TEST(ValidateCli, SeveralPackagesAreMeasuredOnTheSameSimulations) {
  const auto dir = testing::scratch_dir("validate_several");
  auto still = *package();
  still.portrait.q_u.setZero();
  core::write_package(still, dir / "still.h5");
  const auto both =
      testing::run_tool("phasecast-precompute",
                        {"validate", kScene.string(), kPackage.string(), (dir / "still.h5").string(),
                         "--schedule", kStandard, "--random", "1", "--json", (dir / "both.json").string()});
  ASSERT_EQ(both.exit_code, 0) << both.err;
  const auto alone = testing::run_tool(
      "phasecast-precompute", {"validate", kScene.string(), kPackage.string(), "--schedule", kStandard,
                               "--random", "1", "--json", (dir / "alone.json").string()});
  ASSERT_EQ(alone.exit_code, 0) << alone.err;
  nlohmann::json j, one;
  std::ifstream(dir / "both.json") >> j;
  std::ifstream(dir / "alone.json") >> one;
  ASSERT_EQ(j["packages"].size(), 2u);
  EXPECT_EQ(j["packages"][0]["schedules"], one["schedules"]);
  EXPECT_EQ(j["packages"][0]["summary_random"], one["summary_random"]);
  EXPECT_GT(j["packages"][1]["summary_given"]["median_nrmse"].get<double>(), 0.8);  // the still package
  EXPECT_LT(j["packages"][0]["summary_given"]["median_nrmse"].get<double>(), 0.5);
  EXPECT_NE(both.out.find(kPackage.string() + ": given schedules: median NRMSE"), std::string::npos)
      << both.out;
  EXPECT_NE(both.out.find("still.h5: random schedules: median NRMSE"), std::string::npos) << both.out;
  EXPECT_NE(both.out.find("90th percentile"), std::string::npos);

  const auto plant = phasecast::testing::source_dir() / "tests/data/packages/plant_pot.h5";
  const auto mixed = testing::run_tool("phasecast-precompute",
                                       {"validate", kScene.string(), kPackage.string(), plant.string()});
  EXPECT_NE(mixed.exit_code, 0);
  EXPECT_NE(mixed.err.find("validate: " + plant.string() + ": package of scene"), std::string::npos)
      << mixed.err;
  EXPECT_EQ(mixed.out.find("schedule 1/"), std::string::npos) << "nothing is simulated: " << mixed.out;
}

}  // namespace
}  // namespace phasecast::precompute
