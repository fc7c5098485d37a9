// The request service without sockets: several scenes, listings, limits, and
// the rejection paths of snapshots and replays.

#include "error_of.h"
#include "phasecast/server/recording.h"
#include "phasecast/server/synthesis_service.h"
#include "phasecast/server/topic_interest.h"
#include "phasecast/server/wire.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <map>

#include <functional>

namespace phasecast::server {
namespace {

using phasecast::testing::error_of;

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

TEST(Service, ServesSeveralScenesWithTheirOwnRanks) {
  const TwoScenes f("two");
  SynthesisService s(60);
  s.load_package(f.plate);
  s.load_package(f.tall);
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
  const auto& frames = s.tick();
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

// The package's held-out playback figures (/fidelity/) reach clients in the scene list.
TEST(Service, SceneListCarriesThePackagesFidelityAndView) {
  const auto dir = testing::scratch_dir("server_svc_fidelity");
  auto p = testing::make_plate_package();
  core::PlaybackFidelity& f = p.fidelity.emplace();
  f.schedules = 20, f.items = 4, f.seed = 99;
  f.median_nrmse = 0.11f, f.p90_nrmse = 0.21f;
  f.moving = 40, f.moving_within = 37, f.switches = 60, f.switches_within = 58;
  p.attributes.floor = false;
  p.attributes.light = "sky";
  p.attributes.exposure = 1.5f;
  core::write_package(p, dir / "fidelity.h5");
  const TwoScenes plain("fidelity_plain");
  SynthesisService s(60);
  s.load_package(dir / "fidelity.h5");
  s.load_package(plain.tall);
  v1::Request list;
  list.mutable_list_scenes();
  const auto scenes = s.handle(list).scenes();
  ASSERT_EQ(scenes.scenes_size(), 2);
  ASSERT_TRUE(scenes.scenes(0).has_fidelity());
  const auto& got = scenes.scenes(0).fidelity();
  EXPECT_EQ(got.schedules(), 20u);
  EXPECT_EQ(got.seed(), 99);
  EXPECT_FLOAT_EQ(got.median_nrmse(), 0.11f);
  EXPECT_FLOAT_EQ(got.p90_nrmse(), 0.21f);
  EXPECT_EQ(got.moving_within(), 37u);
  EXPECT_EQ(got.switches_within(), 58u);
  EXPECT_FALSE(got.adaptive());
  EXPECT_FALSE(scenes.scenes(1).has_fidelity()) << "a package without /fidelity/ has none";
  // The scene's [view], read back from the package file.
  const auto& view = scenes.scenes(0).view();
  EXPECT_TRUE(view.no_floor());
  EXPECT_FALSE(view.has_floor_height());
  EXPECT_EQ(view.light(), "sky");
  EXPECT_FLOAT_EQ(view.exposure(), 1.5f);
  EXPECT_FALSE(scenes.scenes(1).has_view()) << "a package without a view says nothing";
}

TEST(Service, CreateInstanceIsBounded) {
  const TwoScenes f("bounded");
  SynthesisService s(60);
  s.load_package(f.plate);
  ServiceLimits limits;
  limits.max_instances = 2;
  s.set_limits(limits);
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  EXPECT_TRUE(s.handle(create).ok());
  EXPECT_TRUE(s.handle(create).ok());
  const auto refused = s.handle(create);
  EXPECT_FALSE(refused.ok());
  EXPECT_EQ(refused.error(), "create_instance: 2 instances exist (expected at most 2; see --max-instances)");
  EXPECT_EQ(s.stats().limited_requests, 1u);
}

// One client cannot take every instance; destroying one frees its slot, and
// another client is not affected.
TEST(Service, InstancesPerClientAreBounded) {
  const TwoScenes f("per_client");
  SynthesisService s(60);
  s.load_package(f.plate);
  ServiceLimits limits;
  limits.max_instances_per_client = 2;
  s.set_limits(limits);
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  const auto first = s.handle(create, "a");
  ASSERT_TRUE(first.ok()) << first.error();
  EXPECT_TRUE(s.handle(create, "a").ok());
  EXPECT_EQ(s.handle(create, "a").error(),
            "create_instance: this client created 2 instances (expected at most 2; see "
            "--max-instances-per-client)");
  EXPECT_TRUE(s.handle(create, "b").ok());
  v1::Request destroy;
  destroy.mutable_destroy_instance()->set_instance(first.created().instance());
  ASSERT_TRUE(s.handle(destroy, "b").ok());
  EXPECT_TRUE(s.handle(create, "a").ok());
}

// Defect: 1 024 impulses at frame 2^64 - 1 blocked an instance forever.
TEST(Service, ImpulsesBeyondTheHorizonAreRefused) {
  const TwoScenes f("horizon");
  SynthesisService s(60);
  s.load_package(f.plate);
  s.engine().create_instance("plate");
  v1::Request far;
  far.mutable_impulse()->set_instance(1);
  far.mutable_impulse()->set_name("open");
  far.mutable_impulse()->set_at_frame(~std::uint64_t{0});
  for (int i = 0; i < 2000; ++i) {
    const auto r = s.handle(far);
    ASSERT_FALSE(r.ok());
    ASSERT_EQ(r.error().find("impulse: instance 1: at_frame 18446744073709551615 is"), 0u) << r.error();
    ASSERT_NE(r.error().find("expected at most 36000 frames, 600 s at 60 Hz; see --impulse-horizon"),
              std::string::npos)
        << r.error();
  }
  v1::Request now;
  now.mutable_impulse()->set_instance(1);
  now.mutable_impulse()->set_name("open");
  const auto ok = s.handle(now, "friend");
  EXPECT_TRUE(ok.ok()) << ok.error();
  s.engine().create_instance("plate");
  far.mutable_impulse()->set_instance(2);
  far.mutable_impulse()->set_at_frame(36000);  // exactly at the horizon: accepted
  const auto at_horizon = s.handle(far, "friend");
  EXPECT_TRUE(at_horizon.ok()) << at_horizon.error();
}

// A flood from one client is refused past its budget; another client is not.
TEST(Service, RequestRateIsBoundedPerClient) {
  const TwoScenes f("rate");
  SynthesisService s(60);
  s.load_package(f.plate);
  ServiceLimits limits;
  limits.max_request_rate = 50;
  s.set_limits(limits);
  v1::Request stats;
  stats.mutable_stats();
  int refused = 0;
  std::string error;
  for (int i = 0; i < 500; ++i) {
    const auto r = s.handle(stats, "flood");
    if (!r.ok()) {
      ++refused;
      error = r.error();
    }
  }
  EXPECT_GE(refused, 400);  // the budget is 50 plus what refills while the loop runs
  EXPECT_EQ(error,
            "stats: more than 50 requests/s from this client (expected at most --max-request-rate 50)");
  EXPECT_TRUE(s.handle(stats, "calm").ok());
}

// Large replies stop when the transport's queued reply bytes would pass the
// asking client's bound or the global one; small ones (errors, a short
// stats) always go, and stats report the count.
TEST(Service, LargeRepliesStopAtThePendingReplyBounds) {
  const TwoScenes f("pending");
  SynthesisService s(60);
  s.load_package(f.plate);
  v1::Request chunk;
  chunk.mutable_basis()->set_scene("plate");
  chunk.mutable_basis()->set_part(v1::TRIANGLES);
  const auto first = s.handle(chunk, "slow");
  ASSERT_TRUE(first.ok()) << first.error();
  const std::uint64_t B = first.ByteSizeLong();
  ASSERT_GT(B, kRepliesAlwaysSent);
  ServiceLimits limits;
  limits.max_pending_reply_bytes = 3 * B;
  limits.max_pending_reply_bytes_per_client = 2 * B;
  s.set_limits(limits);
  std::map<std::string, std::uint64_t> pending{{"slow", 0}, {"calm", 0}};
  s.set_pending_reply_bytes([&](const std::string& client) {
    return PendingReplyBytes{pending["slow"] + pending["calm"], pending.count(client) ? pending[client] : 0};
  });
  pending["slow"] = B;
  EXPECT_TRUE(s.handle(chunk, "slow").ok());  // B + B is the client's bound itself
  pending["slow"] = B + 1;
  EXPECT_EQ(
      s.handle(chunk, "slow").error(),
      fmt::format("basis: {} bytes of replies are waiting for this client to read them and this reply has {} "
                  "bytes (expected at most {}; see --max-pending-reply-bytes-per-client)",
                  B + 1, B, 2 * B));
  EXPECT_TRUE(s.handle(chunk, "calm").ok());  // another client is not held back by it
  pending["slow"] = 2 * B;
  pending["calm"] = 1;
  EXPECT_EQ(s.handle(chunk, "calm").error(),
            fmt::format(
                "basis: {} bytes of replies are waiting for clients to read them and this reply has {} bytes "
                "(expected at most {} in all; see --max-pending-reply-bytes)",
                2 * B + 1, B, 3 * B));
  v1::Request stats;
  stats.mutable_stats();
  const auto r = s.handle(stats, "calm");  // small: sent whatever the bounds say
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_LE(r.ByteSizeLong(), kRepliesAlwaysSent);
  EXPECT_EQ(r.stats().pending_reply_bytes(), 2 * B + 1);
  EXPECT_EQ(r.stats().limited_requests(), 2u);
}

// Names travel as bytes; invalid UTF-8 is one counted error with a reply.
TEST(Service, InvalidUtf8IsRefused) {
  const TwoScenes f("utf8");
  SynthesisService s(60);
  s.load_package(f.plate);
  v1::Request create;
  create.mutable_create_instance()->set_scene(std::string("pl\xff\xfe", 4));
  const auto r = s.handle(create.SerializeAsString());
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.error(), "create_instance: scene name is not valid UTF-8 (byte 2 of 4; expected UTF-8 text)");
  for (const std::string bad : {"\xc0\xaf", "\xed\xa0\x80", "\xf4\x90\x80\x80", "\xe2\x82"}) {
    create.mutable_create_instance()->set_scene(bad);
    EXPECT_NE(s.handle(create).error().find("not valid UTF-8"), std::string::npos) << bad.size();
  }
  create.mutable_create_instance()->set_scene("pl\u00e4te");  // valid UTF-8, unknown scene
  EXPECT_NE(s.handle(create).error().find("unknown scene"), std::string::npos);
  // Found by the request fuzzer: a newline or NUL in a name broke or cut the one-line error.
  create.mutable_create_instance()->set_scene(std::string("a\nb", 3));
  EXPECT_EQ(s.handle(create).error(),
            "create_instance: scene name has a control character 0x0a at byte 1 (expected printable text)");
  create.mutable_create_instance()->set_scene(std::string("a\0b", 3));
  EXPECT_EQ(s.handle(create).error(),
            "create_instance: scene name has a control character 0x00 at byte 1 (expected printable text)");
  EXPECT_EQ(s.stats().bad_requests, 8u);
}

TEST(Service, UnknownPackageFailsWithThePath) {
  SynthesisService s(60);
  const auto missing = testing::scratch_dir("server_svc_missing") / "nope.h5";
  EXPECT_NE(error_of([&] { s.load_package(missing); }).find(missing.string()), std::string::npos);
}

TEST(Service, SnapshotsRoundTripAndBadOnesAreRefused) {
  const TwoScenes f("snapshot");
  SynthesisService s(60);
  s.load_package(f.plate);
  auto& e = s.engine();
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, 2);
  for (int i = 0; i < 5; ++i) e.tick();
  v1::InstanceSnapshot snap;
  to_snapshot(e.instance(id).state, snap);
  const auto back = from_snapshot(snap, "here");
  EXPECT_EQ(back.irf, e.instance(id).state.irf);
  EXPECT_EQ(back.offset_q_u, e.instance(id).state.offset_q_u);
  EXPECT_EQ(back.run.group, 2);  // the open IRF started a run of its own group
  EXPECT_EQ(back.run.length, 1u);
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
  s.load_package(f.plate);
  s.engine().create_instance("plate");
  const auto path = f.dir / "small.phcrec";
  s.start_recording(path);
  for (int i = 0; i < 3; ++i) s.tick();
  s.stop_recording();
  return core::read_recording_file(path).entries;
}

TEST(Service, ReplayRefusesEntriesOutOfOrder) {
  const TwoScenes f("order");
  auto entries = small_recording(f);
  ASSERT_EQ(entries.size(), 5u);  // header, created, 3 frames
  auto run = [&](const std::vector<v1::RecordEntry>& es) {
    SynthesisService s(60);
    s.load_package(f.plate);
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

// One request of each kind straight through the service: each reply carries
// its own result, refusals keep their one-line texts.
TEST(Service, AnswersEachRequestKindWithItsResult) {
  const TwoScenes f("kinds");
  SynthesisService s(60);
  s.load_package(f.plate);
  s.set_record_dir(f.dir);
  auto ask = [&](const std::function<void(v1::Request&)>& fill) {
    v1::Request r;
    r.set_id(5);
    fill(r);
    return s.handle(r);
  };
  const auto created = ask([](v1::Request& r) { r.mutable_create_instance()->set_scene("plate"); });
  EXPECT_EQ(created.result_case(), v1::Reply::kCreated);
  EXPECT_EQ(created.created().topic(), "inst/1/");
  const auto impulse = ask([](v1::Request& r) {
    r.mutable_impulse()->set_instance(1);
    r.mutable_impulse()->set_name("open");
  });
  EXPECT_EQ(impulse.result_case(), v1::Reply::kImpulse);
  EXPECT_EQ(impulse.impulse().at_frame(), 0u);
  const auto scenes = ask([](v1::Request& r) { r.mutable_list_scenes(); });
  ASSERT_EQ(scenes.scenes().scenes_size(), 1);
  EXPECT_EQ(ask([](v1::Request& r) { r.mutable_list_instances(); }).instances().instances_size(), 1);
  const auto basis = ask([](v1::Request& r) {
    r.mutable_basis()->set_scene("plate");
    r.mutable_basis()->set_part(v1::TRIANGLES);
  });
  EXPECT_EQ(basis.result_case(), v1::Reply::kBasis);
  EXPECT_EQ(basis.basis().total_bytes(), basis.basis().data().size());
  EXPECT_EQ(ask([](v1::Request& r) { r.mutable_record_stop(); }).error(),
            "record_stop: not recording (expected a record_start first)");
  const auto started = ask([](v1::Request& r) { r.mutable_record_start()->set_path("kinds.phcrec"); });
  EXPECT_TRUE(started.record().recording());
  EXPECT_EQ(started.record().path(), (f.dir / "kinds.phcrec").string());
  s.tick();
  const auto stats = ask([](v1::Request& r) { r.mutable_stats(); }).stats();
  EXPECT_EQ(stats.ticks(), 1u);
  EXPECT_EQ(stats.impulses_applied(), 1u);
  EXPECT_TRUE(stats.recording());
  EXPECT_EQ(stats.instances_size(), 1);
  auto destroy = [](v1::Request& r) { r.mutable_destroy_instance()->set_instance(1); };
  const auto destroyed = ask(destroy);
  EXPECT_EQ(destroyed.destroyed().frame(), 1u);
  EXPECT_EQ(ask(destroy).error(),
            "destroy_instance: unknown instance 1 (expected one of the 0 existing instances)");
  EXPECT_EQ(ask([](v1::Request& r) { r.mutable_record_stop(); }).record().frames_written(), 1u);
  const auto entries = core::read_recording_file(f.dir / "kinds.phcrec").entries;
  ASSERT_EQ(entries.size(), 5u);  // header, created, impulse, frame, destroyed
  EXPECT_EQ(entries[4].destroyed().frame(), 1u);
}

// A subscription is a topic prefix: what it reaches is what tick() builds.
TEST(Service, TopicInterestMatchesPrefixesAsZeroMqDoes) {
  TopicInterest t;
  EXPECT_TRUE(t.wants_instance(3)) << "before any subscription: every Frame (tests read the tick)";
  EXPECT_FALSE(t.wants("scene/plate/0/")) << "and no batch";
  t.set({"inst/1"});
  EXPECT_TRUE(t.wants_instance(1));
  EXPECT_TRUE(t.wants_instance(12)) << "inst/1 is a prefix of inst/12/";
  EXPECT_FALSE(t.wants_instance(2));
  t.set({"inst/1/", "scene/plate/"});
  EXPECT_FALSE(t.wants_instance(12)) << "the cache follows the subscriptions";
  EXPECT_TRUE(t.wants("scene/plate/3/"));
  EXPECT_FALSE(t.wants("scene/tall/0/"));
  t.set({""});
  EXPECT_TRUE(t.wants_instance(99));
  EXPECT_TRUE(t.wants("scene/tall/0/"));
  t.set({});
  EXPECT_FALSE(t.wants_instance(1));
  EXPECT_FALSE(t.wants("scene/plate/0/"));
}

// The frames of the instances of one scene whose ids share a block.
std::map<std::string, v1::FrameBatch> batches_of(const std::vector<PublishedFrame>& published) {
  std::map<std::string, v1::FrameBatch> out;
  for (const auto& m : published) {
    if (m.topic.starts_with("scene/")) {
      EXPECT_TRUE(out[m.topic].ParseFromString(m.payload));
    }
  }
  return out;
}

// Batches carry, field by field, what each instance's own Frame carries; a
// scene's instances split by blocks of kFrameBatchBlock ids; nothing is
// built that nobody subscribes to.
TEST(Service, FrameBatchesCarryWhatFramesCarryPerSceneAndBlock) {
  const TwoScenes f("batches");
  std::vector<std::unique_ptr<SynthesisService>> services;
  for (int i = 0; i < 3; ++i) {
    auto& s = *services.emplace_back(std::make_unique<SynthesisService>(60));
    s.load_package(f.plate);
    s.load_package(f.tall);
    for (std::uint32_t id = 1; id <= kFrameBatchBlock + 6; ++id) s.engine().create_instance("plate");
    s.engine().create_instance("tall");
    s.engine().create_instance("tall");
    s.engine().schedule_impulse(5, s.engine().palette_index(5, "open"), std::nullopt);  // one moves
  }
  SynthesisService &frames = *services[0], &all_batches = *services[1], &some = *services[2];
  all_batches.set_subscriptions({"scene/"});
  some.set_subscriptions({"scene/plate/1/", "inst/7/"});
  for (int t = 0; t < 3; ++t) {
    std::map<std::uint32_t, v1::Frame> by_instance;
    for (const auto& m : frames.tick()) {
      v1::Frame fr;
      ASSERT_TRUE(fr.ParseFromString(m.payload));
      by_instance[fr.instance()] = fr;
    }
    ASSERT_EQ(by_instance.size(), kFrameBatchBlock + 8);
    const auto& published = all_batches.tick();
    const auto batches = batches_of(published);
    ASSERT_EQ(published.size(), 3u) << "no Frame messages, three batches";
    ASSERT_EQ(batches.size(), 3u);
    EXPECT_EQ(batches.at("scene/plate/0/").instance_size(), static_cast<int>(kFrameBatchBlock) - 1);
    EXPECT_EQ(batches.at("scene/plate/1/").instance_size(), 7);
    EXPECT_EQ(batches.at("scene/tall/1/").instance_size(), 2);
    for (const auto& [topic, b] : batches) {
      EXPECT_EQ(b.tick(), static_cast<std::uint64_t>(t));
      const int ru = static_cast<int>(b.rank_u()), ra = static_cast<int>(b.rank_a());
      ASSERT_EQ(b.q_u_size(), ru * b.instance_size());
      ASSERT_EQ(b.q_a_size(), ra * b.instance_size());
      ASSERT_EQ(b.support_size(), 12 * b.instance_size());
      for (int i = 0; i < b.instance_size(); ++i) {
        const auto& fr = by_instance.at(b.instance(i));
        EXPECT_EQ(topic, fmt::format("scene/{}/{}/", fr.scene(), fr.instance() / kFrameBatchBlock));
        EXPECT_EQ(b.frame(i), fr.frame());
        for (int k = 0; k < ru; ++k) ASSERT_EQ(b.q_u(ru * i + k), fr.q_u(k)) << "instance " << fr.instance();
        for (int k = 0; k < ra; ++k) ASSERT_EQ(b.q_a(ra * i + k), fr.q_a(k));
        for (int k = 0; k < 12; ++k) ASSERT_EQ(b.support(12 * i + k), fr.support(k));
        EXPECT_EQ(b.palette_index(i), fr.palette_index());
        EXPECT_EQ(b.irf(i), fr.irf());
        EXPECT_EQ(b.irf_t(i), fr.irf_t());
      }
    }
    const auto& chosen = some.tick();
    ASSERT_EQ(chosen.size(), 2u);
    EXPECT_EQ(chosen[0].topic, "inst/7/");
    EXPECT_EQ(chosen[1].topic, "scene/plate/1/");
  }
  EXPECT_GT(batches_of(all_batches.tick()).at("scene/plate/0/").palette_index(4), -1)
      << "instance 5 plays its impulse";
  EXPECT_EQ(all_batches.stats().frames_published, 0u);
  EXPECT_EQ(all_batches.stats().batches_published, 12u);
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
