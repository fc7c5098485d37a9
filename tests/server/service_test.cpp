// The request service without sockets: several scenes, listings, limits, and
// the rejection paths of snapshots and replays.

#include "phasecast/server/recording.h"
#include "phasecast/server/synthesis_service.h"
#include "phasecast/server/wire.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>

#include <functional>

namespace phasecast::server {
namespace {

using Clock = std::chrono::steady_clock;

// plate.h5 (r_u = 4) and tall.h5: another scene, "tall", with r_u = 6 and no appearance.
struct TwoScenes {
  std::filesystem::path dir, plate, tall;
  explicit TwoScenes(const std::string& name)
      : dir(testing::scratch_dir("server_svc_" + name)), plate(dir / "plate.h5"), tall(dir / "tall.h5") {
    core::write_package(testing::make_plate_package(), plate);
    testing::PlateOptions o;
    o.rank_u = 6;
    o.appearance = false;
    auto p = testing::make_plate_package(o);
    p.attributes.scene = "tall";
    core::write_package(p, tall);
  }
};

template <class Fn>
std::string error_of(Fn&& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Service, ServesSeveralScenesWithTheirOwnRanks) {
  const TwoScenes f("two");
  SynthesisService s(60);
  s.load_scene(f.plate);
  s.load_scene(f.tall);
  v1::Request list;
  list.mutable_list_scenes();
  const auto scenes = s.handle(list).scenes();
  ASSERT_EQ(scenes.scenes_size(), 2);
  EXPECT_EQ(scenes.scenes(1).name(), "tall");
  EXPECT_EQ(scenes.scenes(1).rank_u(), 6u);
  EXPECT_EQ(scenes.scenes(1).rank_a(), 0u);
  EXPECT_EQ(scenes.scenes(1).parts_size(), 6) << "no appearance parts without an appearance model";
  v1::Request create;
  create.mutable_create_instance()->set_scene("tall");
  ASSERT_TRUE(s.handle(create).ok());
  create.mutable_create_instance()->set_scene("plate");
  ASSERT_TRUE(s.handle(create).ok());
  const auto& frames = s.tick(Clock::now());
  ASSERT_EQ(frames.size(), 2u);
  v1::Frame a, b;
  ASSERT_TRUE(a.ParseFromString(frames[0].payload));
  ASSERT_TRUE(b.ParseFromString(frames[1].payload));
  EXPECT_EQ(frames[0].topic, "inst/1/");
  EXPECT_EQ(a.scene(), "tall");
  EXPECT_EQ(a.q_u_size(), 6);
  EXPECT_EQ(a.q_a_size(), 0);
  EXPECT_EQ(b.scene(), "plate");
  EXPECT_EQ(b.q_u_size(), 4);
}

TEST(Service, CreateInstanceIsBounded) {
  const TwoScenes f("bounded");
  SynthesisService s(60);
  s.load_scene(f.plate);
  s.set_max_instances(2);
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  EXPECT_TRUE(s.handle(create).ok());
  EXPECT_TRUE(s.handle(create).ok());
  const auto refused = s.handle(create);
  EXPECT_FALSE(refused.ok());
  EXPECT_EQ(refused.error(), "create_instance: 2 instances exist (expected at most 2; see --max-instances)");
}

TEST(Service, UnknownPackageFailsWithThePath) {
  SynthesisService s(60);
  const auto missing = testing::scratch_dir("server_svc_missing") / "nope.h5";
  EXPECT_NE(error_of([&] { s.load_scene(missing); }).find(missing.string()), std::string::npos);
}

TEST(Service, SnapshotsRoundTripAndBadOnesAreRefused) {
  const TwoScenes f("snapshot");
  SynthesisService s(60);
  s.load_scene(f.plate);
  auto& e = s.engine();
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, 2);
  for (int i = 0; i < 5; ++i) e.tick();
  v1::InstanceSnapshot snap;
  to_snapshot(e.instance(id).state, snap);
  const auto back = from_snapshot(snap, "here");
  EXPECT_EQ(back.irf, e.instance(id).state.irf);
  EXPECT_EQ(back.offset_q_u, e.instance(id).state.offset_q_u);
  snap.set_mode(7);
  EXPECT_EQ(error_of([&] { from_snapshot(snap, "record 3"); }),
            "record 3: snapshot mode 7 (expected 0 rest or 1 playing)");
  InstanceState resting = e.instance(id).state;
  resting.mode = Mode::rest;  // but still naming an IRF and entry
  EXPECT_EQ(error_of([&] {
              e.restore_instance(9, "plate", 0, resting);
            }).rfind("instance 9 (plate): inconsistent state (expected IRF, node and entry indices", 0),
            0u);
}

std::vector<v1::RecordEntry> small_recording(const TwoScenes& f) {
  SynthesisService s(60);
  s.load_scene(f.plate);
  s.engine().create_instance("plate");
  const auto path = f.dir / "small.phcrec";
  s.start_recording(path);
  for (int i = 0; i < 3; ++i) s.tick(Clock::now());
  s.stop_recording();
  return read_recording(path);
}

TEST(Service, ReplayRefusesEntriesOutOfOrder) {
  const TwoScenes f("order");
  auto entries = small_recording(f);
  ASSERT_EQ(entries.size(), 5u);  // header, created, 3 frames
  auto run = [&](const std::vector<v1::RecordEntry>& es) {
    SynthesisService s(60);
    s.load_scene(f.plate);
    return error_of([&] { replay_check(s.engine(), es); });
  };
  EXPECT_EQ(run(entries), "(no error)");
  auto skipped = entries;
  skipped.erase(skipped.begin() + 3);  // frame 1 missing
  EXPECT_EQ(run(skipped),
            "replay-check: record 3: frame 2 of instance 1 out of order (the replay is at frame 1)");
  auto twice = entries;
  twice.insert(twice.begin() + 2, entries.front());
  EXPECT_EQ(run(twice), "replay-check: record 2 is a second header");
  auto unknown = entries;
  unknown[4].mutable_frame()->set_instance(5);
  EXPECT_EQ(run(unknown), "replay-check: unknown instance 5 (expected one of the 1 existing instances)");
}

TEST(Service, ToolHasHelp) {
  const auto r = testing::run_tool("phasecast-server", {"--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* opt :
       {"--cmd", "--pub", "--rate", "--instances", "--record", "--replay-check", "--blend-lambda"}) {
    EXPECT_NE(r.out.find(opt), std::string::npos) << opt;
  }
}

}  // namespace
}  // namespace phasecast::server
