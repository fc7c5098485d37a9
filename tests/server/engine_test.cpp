// Unit tests of the synthesis engine (paper §5) on the synthetic plate scene:
// IRF switching through the §5.2 cache, eq. 12 blending, end-of-IRF rules,
// palette transitions, support kinematics, target frames and determinism.

#include "error_of.h"
#include "phasecast/server/synthesis_engine.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <tuple>
#include <utility>

namespace phasecast::server {
namespace {

using phasecast::testing::error_of;

using Package = std::shared_ptr<const core::ScenePackage>;

Package plate(const testing::PlateOptions& o = {}) {
  return std::make_shared<const core::ScenePackage>(testing::make_plate_package(o));
}

const Package& default_plate() {
  static const Package p = plate();
  return p;
}

SynthesisEngine engine_with(const Package& p, std::optional<double> lambda = std::nullopt) {
  SynthesisEngine e;
  e.add_scene(p, "plate.h5", 42, lambda);
  return e;
}

constexpr int kOpen = 2, kStop = 1, kClose = 0;

// The frame `r` holds for instance `id`.
const SynthesizedFrame& frame_of(const TickResult& r, std::uint32_t id) {
  for (const auto& f : r.frames) {
    if (f.instance == id) return f;
  }
  throw std::out_of_range("instance " + std::to_string(id) + " made no frame this tick");
}

// Ticks `e` and returns the frame of instance `id` (a copy: the tick's result is gone after).
SynthesizedFrame tick_frame(SynthesisEngine& e, std::uint32_t id) {
  return frame_of(e.tick(), id);
}

TEST(Engine, NewInstanceRestsOnTheNodeNearestTheRestShape) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  EXPECT_EQ(id, 1u);
  const int rest = e.scenes()[0].rest_node;
  for (int f = 0; f < 5; ++f) {
    const auto last = tick_frame(e, id);
    EXPECT_EQ(last.frame, static_cast<std::uint64_t>(f));
    EXPECT_EQ(last.palette_index, -1);
    EXPECT_EQ(last.irf, -1);
    EXPECT_EQ(last.q_u, VectorXf(default_plate()->portrait.q_u.row(rest).transpose()));
    EXPECT_EQ(last.q_a, VectorXf(default_plate()->portrait.q_a.row(rest).transpose()));
  }
}

TEST(Engine, ImpulseSwitchesToTheCachedNearestIrfInTheNextFrame) {
  const auto& pkg = *default_plate();
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  const VectorXf before = tick_frame(e, id).q_u;
  EXPECT_EQ(e.schedule_impulse(id, kOpen), 1u);
  const auto r = e.tick();
  ASSERT_EQ(r.applied.size(), 1u);
  EXPECT_EQ(r.applied[0].frame, 1u);
  const auto& last = frame_of(r, id);
  EXPECT_EQ(last.palette_index, kOpen);
  EXPECT_EQ(last.irf, pkg.portrait.nearest_irf(e.scenes()[0].rest_node, kOpen));
  EXPECT_EQ(last.irf_t, 0u);
  // Eq. 12 at t = 0: the frame is the state the impulse arrived in.
  EXPECT_LT((last.q_u - before).norm(), 1e-6f);
}

struct Switch {
  float step_before = 0;  // largest |Δq_u| over the 5 frames before the switch frame
  float step_into = 0;    // |Δq_u| into the switch frame
  float step_after = 0;   // |Δq_u| out of it
  float offset = 0;       // |x' - x_j(0)| (eq. 12)
  float qdot_start = 0;   // |q̇_u| at the start of the new IRF
};

// Plays `open`, then `stop` in mid-swing, and measures the steps around the switch.
Switch measure_switch(std::optional<double> lambda) {
  const auto& pp = default_plate()->portrait;
  auto e = engine_with(default_plate(), lambda);
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  Switch s;
  VectorXf prev;
  for (int i = 0; i < 37; ++i) {
    const VectorXf q_u = tick_frame(e, id).q_u;
    if (i >= 32) s.step_before = std::max(s.step_before, (q_u - prev).norm());
    prev = q_u;
  }
  e.schedule_impulse(id, kStop);
  const auto switched = tick_frame(e, id);
  s.step_into = (switched.q_u - prev).norm();
  prev = switched.q_u;
  const int start = pp.irf_start[static_cast<size_t>(switched.irf)];
  s.offset = (prev - pp.q_u.row(start).transpose()).norm();
  s.qdot_start = pp.qdot_u.row(start).norm();
  s.step_after = (tick_frame(e, id).q_u - prev).norm();
  return s;
}

// Eq. 12's trajectory x_j(t) + offset e^(-λt) moves at most |q̇_j(0)| + λ|offset| at the switch.
TEST(Engine, BlendedSwitchDoesNotJumpFasterThanTheLocalVelocity) {
  const double lambda = default_plate()->attributes.blend_lambda, dt = default_plate()->attributes.dt;
  const Switch s = measure_switch(std::nullopt);
  ASSERT_GT(s.offset, 0.05f) << "the switch must need blending for this test to mean something";
  const float local = static_cast<float>(dt * (s.qdot_start + lambda * s.offset));
  EXPECT_LE(s.step_into, 1.05f * s.step_before + 1e-6f);
  EXPECT_LE(s.step_after, 1.05f * local + 1e-6f);
  const Switch pop = measure_switch(1e9);  // no blending: the switch jumps by the whole offset
  EXPECT_GT(pop.step_after, 2 * local);
}

TEST(Engine, BlendOffsetDecaysOntoTheTargetIrf) {
  const auto& pkg = *default_plate();
  const auto& pp = pkg.portrait;
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  for (int i = 0; i < 30; ++i) e.tick();
  e.schedule_impulse(id, kStop);
  auto f = tick_frame(e, id);
  const int irf = f.irf, start = pp.irf_start[static_cast<size_t>(irf)];
  const VectorXf offset = f.q_u - pp.q_u.row(start).transpose();
  ASSERT_GT(offset.norm(), 1e-3f);
  for (int t = 1; t < 60; ++t) {
    f = tick_frame(e, id);
    ASSERT_EQ(f.irf, irf);
    ASSERT_EQ(f.irf_t, static_cast<std::uint32_t>(t));
    const float w = static_cast<float>(std::exp(-pkg.attributes.blend_lambda * t * pkg.attributes.dt));
    const VectorXf expected = pp.q_u.row(start + t).transpose() + w * offset;  // eq. 12
    EXPECT_LT((f.q_u - expected).norm(), 1e-5f) << "t = " << t;
  }
  const VectorXf residual = f.q_u - pp.q_u.row(start + 59).transpose();
  EXPECT_LT(residual.norm(), 2e-3f * offset.norm());
}

TEST(Engine, TheDoorKeepsOpeningUntilItsStopThenTheFollowUpThenRest) {
  const auto& pkg = *default_plate();
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  const auto& k = pkg.palette.kinematics[kOpen];
  // An open IRF that runs out before the door reaches its stop is continued
  // by another open IRF: the interaction persists while the door can move.
  auto stop = tick_frame(e, id);
  int frames = 0, irfs = 1;
  bool extended = false;  // an IRF ran out and play went on inside another (the orbit extension)
  for (int irf = stop.irf; stop.palette_index == kOpen && frames < 10000; stop = tick_frame(e, id)) {
    ++frames;
    const bool switched = std::exchange(irf, stop.irf) != stop.irf;
    irfs += switched;
    extended |= switched && stop.irf_t > 0;
  }
  const double swept = frames * pkg.attributes.dt * k.rate;  // on_end(open) = stop, at the range end
  EXPECT_NEAR(swept, k.range_max, k.rate * pkg.attributes.dt + 1e-6) << "the door opened " << swept << " rad";
  EXPECT_GT(frames, pkg.portrait.irf_length[static_cast<size_t>(pkg.portrait.nearest_irf(0, kOpen))]);
  EXPECT_GE(irfs, 2);
  EXPECT_TRUE(extended);
  EXPECT_EQ(stop.palette_index, kStop);
  EXPECT_EQ(pkg.portrait.irf_palette[static_cast<size_t>(stop.irf)], kStop);
  EXPECT_EQ(stop.irf_t, 0u);
  const int stop_irf = stop.irf;
  const int stop_len = pkg.portrait.irf_length[static_cast<size_t>(stop_irf)];
  for (int t = 1; t < stop_len; ++t) e.tick();
  const auto rest = tick_frame(e, id);  // on_end(stop) = rest: hold the last node
  EXPECT_EQ(rest.palette_index, -1);
  EXPECT_EQ(rest.irf, -1);
  const int last_node = pkg.portrait.irf_start[static_cast<size_t>(stop_irf)] + stop_len - 1;
  const float w = static_cast<float>(std::exp(-pkg.attributes.blend_lambda * stop_len * pkg.attributes.dt));
  EXPECT_LT((rest.q_u - pkg.portrait.q_u.row(last_node).transpose()).norm(), 2 * w + 1e-6f);
  // From rest at its stop the door may close again, but not open further.
  EXPECT_EQ(e.allowed_entries(id), std::vector<int>{kClose});
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kOpen); }),
            "instance 1 (plate): 'open' cannot move the support: s = 1.571 is at the end of its range [0, "
            "1.571] (rule: support range)");
  EXPECT_NO_THROW(e.schedule_impulse(id, kClose));
}

// range_min == range_max means an unlimited support (as in the sampler): the
// entry plays its IRF out and the support keeps moving.
TEST(Engine, AnUnlimitedSupportIsNeverAtTheEndOfItsRange) {
  auto p = testing::make_plate_package();
  for (auto& k : p.palette.kinematics) k.range_min = k.range_max = 0;
  const auto pkg = std::make_shared<const core::ScenePackage>(std::move(p));
  auto e = engine_with(pkg);
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  const auto first = tick_frame(e, id);
  const int len = pkg->portrait.irf_length[static_cast<size_t>(first.irf)];
  auto f = first;
  for (int t = 1; t < len; ++t) f = tick_frame(e, id);
  EXPECT_EQ(f.irf, first.irf);
  EXPECT_EQ(f.irf_t, static_cast<std::uint32_t>(len - 1));
  EXPECT_NE(f.support, first.support);  // the door turned
}

// Eq. 9 between two nodes (b = -1: the origin), in double.
double node_distance(const core::ScenePackage& pkg, int a, int b) {
  const auto& pp = pkg.portrait;
  const auto row = [](const MatrixXfR& m, int n) -> Eigen::RowVectorXd {
    return n < 0 ? Eigen::RowVectorXd::Zero(m.cols()) : Eigen::RowVectorXd(m.row(n).cast<double>());
  };
  return std::sqrt((row(pp.q_u, a) - row(pp.q_u, b)).squaredNorm() +
                   pkg.attributes.beta * (row(pp.qdot_u, a) - row(pp.qdot_u, b)).squaredNorm());
}

// The portrait's radius: the largest eq. 9 distance of a node from the origin.
double portrait_radius(const core::ScenePackage& pkg) {
  double radius = 0;
  for (int n = 0; n < pkg.portrait.nodes(); ++n) radius = std::max(radius, node_distance(pkg, n, -1));
  return radius;
}

TEST(Engine, HoldRuleContinuesAtTheNearestNodeOfAnotherIrfOfTheSameEntry) {
  testing::PlateOptions o;
  o.irfs_per_entry = 5;  // several other IRFs to choose among
  o.appearance = false;
  auto p = testing::make_plate_package(o);
  p.palette.on_end[kOpen] = core::kEndHold;
  p.palette.kinematics[kOpen].rate = 0;  // keep the range from ending it first
  const auto pkg = std::make_shared<const core::ScenePackage>(std::move(p));
  const auto& pp = pkg->portrait;
  auto e = engine_with(pkg);
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  auto f = tick_frame(e, id);
  const int irf = f.irf;
  const int len = pp.irf_length[static_cast<size_t>(irf)];
  for (int t = 1; t <= len; ++t) f = tick_frame(e, id);
  EXPECT_EQ(f.palette_index, kOpen);
  // Brute force in double from the state the hold blends from (the last node
  // one step on): of each other IRF of the entry its nearest node past the
  // start with 2 frames left; of those within 1 % of the portrait's radius of
  // the nearest, the one with most frames left.
  const int last_node = pp.irf_start[static_cast<size_t>(irf)] + len - 1;
  const Eigen::RowVectorXd qdot = pp.qdot_u.row(last_node).cast<double>();
  const Eigen::RowVectorXd q = pp.q_u.row(last_node).cast<double>() + pkg->attributes.dt * qdot;
  const auto distance = [&](int node) {
    return std::sqrt((pp.q_u.row(node).cast<double>() - q).squaredNorm() +
                     pkg->attributes.beta * (pp.qdot_u.row(node).cast<double>() - qdot).squaredNorm());
  };
  const double radius = portrait_radius(*pkg);
  std::vector<std::tuple<double, int, int>> nearest_of_each;  // distance, IRF, step
  for (int j = 0; j < pp.irf_count(); ++j) {
    if (j == irf || pp.irf_palette[static_cast<size_t>(j)] != kOpen) continue;
    std::tuple<double, int, int> c{std::numeric_limits<double>::infinity(), j, -1};
    for (int t = 1; t + 2 <= pp.irf_length[static_cast<size_t>(j)]; ++t)
      c = std::min(c, std::tuple(distance(pp.irf_start[static_cast<size_t>(j)] + t), j, t));
    if (std::get<2>(c) > 0) nearest_of_each.push_back(c);
  }
  ASSERT_GE(nearest_of_each.size(), 2u) << "vacuous: the plate needs several other open IRFs";
  const double nearest = std::get<0>(*std::ranges::min_element(nearest_of_each));
  const auto frames_left = [&](const auto& c) {
    return pp.irf_length[static_cast<size_t>(std::get<1>(c))] - std::get<2>(c);
  };
  std::tuple<double, int, int> expected{0, -1, 0};
  for (const auto& c : nearest_of_each) {
    if (std::get<0>(c) > nearest + 0.01 * radius) continue;
    if (std::get<1>(expected) < 0 || frames_left(c) > frames_left(expected) ||
        (frames_left(c) == frames_left(expected) && std::get<0>(c) < std::get<0>(expected)))
      expected = c;
  }
  EXPECT_EQ(f.irf, std::get<1>(expected));
  EXPECT_EQ(f.irf_t, static_cast<std::uint32_t>(std::get<2>(expected)));
  // Eq. 12 from that node: the offset is taken there and decays from the next frame.
  const int node = pp.irf_start[static_cast<size_t>(f.irf)] + static_cast<int>(f.irf_t);
  const auto next = tick_frame(e, id);
  ASSERT_EQ(next.irf, f.irf);
  ASSERT_EQ(next.irf_t, f.irf_t + 1);
  const float w = static_cast<float>(std::exp(-pkg->attributes.blend_lambda * pkg->attributes.dt));
  const VectorXf expected_q = pp.q_u.row(node + 1).transpose() + w * (f.q_u - pp.q_u.row(node).transpose());
  EXPECT_LT((next.q_u - expected_q).norm(), 1e-5f * (1 + expected_q.norm()));
}

// The extension's rule on nodes placed by hand around the state IRF a's hold
// blends from (x: a's last node one step on). IRF b: its start is x itself, a
// start being the impulse's onset again; its step 5 is nearest. IRF c: its
// step 1 is within the 1 % band of the nearest and has more frames left; its
// last step is x too, with too few frames left. The rule and each of its three
// mutants (starts allowed, 1 frame left allowed, no band) pick different nodes.
TEST(Engine, OrbitExtensionSkipsStartsAndShortTailsAndPrefersMoreFramesLeftWithinTheBand) {
  testing::PlateOptions o;
  o.irfs_per_entry = 3;
  o.appearance = false;
  auto p = testing::make_plate_package(o);  // `open` drives the door's limited range: it holds
  auto& pp = p.portrait;
  std::vector<int> open;
  for (int j = 0; j < pp.irf_count(); ++j)
    if (pp.irf_palette[static_cast<size_t>(j)] == kOpen) open.push_back(j);
  ASSERT_EQ(open.size(), 3u);
  const int a = open[0], b = open[1], c = open[2];
  const auto start = [&](int j) { return pp.irf_start[static_cast<size_t>(j)]; };
  const auto length = [&](int j) { return pp.irf_length[static_cast<size_t>(j)]; };
  const double radius = portrait_radius(p);
  const int last = start(a) + length(a) - 1;
  const Eigen::RowVectorXf qdot = pp.qdot_u.row(last);
  const Eigen::RowVectorXf x = pp.q_u.row(last) + static_cast<float>(p.attributes.dt) * qdot;
  Eigen::RowVectorXf along = Eigen::RowVectorXf::Zero(x.size());
  along[0] = static_cast<float>(radius);
  const auto place = [&](int j, int t, float offset) {
    pp.q_u.row(start(j) + t) = x + offset * along;
    pp.qdot_u.row(start(j) + t) = qdot;
  };
  for (const int j : {b, c})
    for (int t = 0; t < length(j); ++t) place(j, t, 0.5f);  // far from x
  place(b, 0, 0);
  place(b, 5, 0.002f);
  place(c, 1, 0.008f);  // within 0.002 + 1 % of the radius while the radius keeps 60 % of itself
  place(c, length(c) - 1, 0);
  ASSERT_GE(portrait_radius(p), 0.6 * radius) << "the band would no longer reach c's step 1";
  auto e = engine_with(std::make_shared<const core::ScenePackage>(std::move(p)));
  const auto& extension = e.scenes()[0].extension[static_cast<size_t>(a)];
  EXPECT_EQ(extension.irf, c);
  EXPECT_EQ(extension.t, 1);
}

TEST(Engine, DoorStopsWhenItReachesTheEndOfItsRange) {
  testing::PlateOptions o;
  o.irf_length = 200;  // longer than the 2 s the door needs to open 90 degrees
  const auto pkg = plate(o);
  auto e = engine_with(pkg);
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  const int frames_to_open =
      static_cast<int>(std::ceil((std::numbers::pi / 2) / (std::numbers::pi / 4) * 60));
  int switched_at = -1;
  SynthesizedFrame last;
  for (int f = 0; f < 199 && switched_at < 0; ++f) {
    last = tick_frame(e, id);
    if (last.palette_index == kStop) switched_at = f;
  }
  EXPECT_NEAR(switched_at, frames_to_open, 1);
  // Rotation about +y by 90 degrees: R(0,0) = cos = 0, R(0,2) = sin = 1.
  const auto& s = last.support;
  EXPECT_NEAR(s[0], 0.0f, 1e-6f);
  EXPECT_NEAR(s[2], 1.0f, 1e-6f);
}

TEST(Engine, SupportTransformRotatesAboutThePivotOrTranslates) {
  core::SupportKinematics k;
  k.axis = {0, 1, 0};
  k.pivot = {1, 0, 2};
  k.rotational = true;
  const auto m = support_transform(k, std::numbers::pi / 2);
  // The pivot is fixed: R p + t = p.
  for (int r = 0; r < 3; ++r) {
    const float y = m[4 * r] * 1 + m[4 * r + 1] * 0 + m[4 * r + 2] * 2 + m[4 * r + 3];
    EXPECT_NEAR(y, k.pivot[static_cast<size_t>(r)], 1e-6f);
  }
  k.rotational = false;
  k.axis = {0, 0, 1};
  const auto t = support_transform(k, 0.25);
  EXPECT_EQ(t, (std::array<float, 12>{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.25f}));
}

TEST(Engine, JoltIsADisplacementPulseThatReturnsToRest) {
  auto p = testing::make_plate_package();
  auto& k = p.palette.kinematics[kOpen];
  k.rotational = false;
  k.axis = {1, 0, 0};
  k.rate = 2;  // m/s initial speed
  k.pulse_tau = 0.1f;
  k.range_min = -1;
  k.range_max = 1;
  const auto pkg = std::make_shared<const core::ScenePackage>(std::move(p));
  auto e = engine_with(pkg);
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  float peak = 0;
  SynthesizedFrame last;
  for (int f = 0; f < 60; ++f) {
    last = tick_frame(e, id);
    peak = std::max(peak, last.support[3]);
  }
  EXPECT_NEAR(peak, 2 * 0.1 / std::numbers::e, 2e-3);  // rate * tau / e
  EXPECT_LT(std::abs(last.support[3]), 2e-3f);
}

TEST(Engine, ImpulseLandsExactlyInItsTargetFrame) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  EXPECT_EQ(e.schedule_impulse(id, kOpen, 10), 10u);
  for (int f = 0; f < 10; ++f) {
    const auto r = e.tick();
    EXPECT_TRUE(r.applied.empty());
    EXPECT_EQ(frame_of(r, id).palette_index, -1);
  }
  const auto r = e.tick();
  ASSERT_EQ(r.applied.size(), 1u);
  EXPECT_EQ(r.applied[0].frame, 10u);
  EXPECT_EQ(frame_of(r, id).frame, 10u);
  EXPECT_EQ(frame_of(r, id).palette_index, kOpen);
}

// §3.5: a closed door cannot be closed. The sampler never drew such an IRF
// (PaletteRules::reachable_frames), so the server refuses it by the same test.
TEST(Engine, AnEntryThatCannotMoveTheSupportIsRefusedNamingTheRange) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  EXPECT_EQ(e.allowed_entries(id), std::vector<int>{kOpen});
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kClose); }),
            "instance 1 (plate): 'close' cannot move the support: s = 0 is at the end of its range [0, "
            "1.571] (rule: support range)");
  // Queued for a later frame it is accepted, then refused when its frame comes.
  e.schedule_impulse(id, kClose, 3);
  TickResult r;
  for (int f = 0; f <= 3; ++f) r = e.tick();
  ASSERT_EQ(r.refused.size(), 1u);
  EXPECT_EQ(r.refused[0].error,
            "'close' cannot move the support: s = 0 is at the end of its range [0, 1.571] (rule: support "
            "range)");
  EXPECT_EQ(frame_of(r, id).palette_index, -1);
}

// The pot's "at most two same-signed pushes in a row" (§3.5): a run of one
// group longer than /palette/max_in_a_row is refused, now and when it lands;
// an entry of another group ends the run, and coming to rest does not (as in
// a sampled chain).
TEST(Engine, MaxInARowLimitsRunsOfOneGroup) {
  auto p = testing::make_plate_package();
  p.palette.transitions.setOnes();
  for (auto& k : p.palette.kinematics) k.range_min = k.range_max = 0;  // unlimited: only the run counts
  p.palette.group = {kClose, kStop, kClose};                           // open and close: one group "swing"
  p.palette.max_in_a_row = {2, 0, 2};
  p.palette.on_end = {core::kEndRest, core::kEndRest, core::kEndRest};
  const auto pkg = std::make_shared<const core::ScenePackage>(std::move(p));
  auto e = engine_with(pkg);
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen);
  e.tick();
  e.schedule_impulse(id, kClose, 5);
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kOpen, 6); }),
            "instance 1 (plate): 'open' is not allowed: 2 IRFs of 'close', 'open' already in a row (rule "
            "max_in_a_row = 2)");
  for (int f = 1; f <= 5; ++f) e.tick();
  EXPECT_EQ(e.instance(id).state.run.length, 2u);
  EXPECT_EQ(e.allowed_entries(id), std::vector<int>{kStop});
  // Played out to rest, the run still stands.
  while (e.instance(id).state.mode != Mode::rest) e.tick();
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kClose); }),
            "instance 1 (plate): 'close' is not allowed: 2 IRFs of 'close', 'open' already in a row (rule "
            "max_in_a_row = 2)");
  // A stop ends it.
  e.schedule_impulse(id, kStop);
  e.tick();
  EXPECT_EQ(e.instance(id).state.run.length, 1u);
  EXPECT_NO_THROW(e.schedule_impulse(id, kOpen));
}

TEST(Engine, ImpulsesOfOneFrameApplyInArrivalOrderTheLaterWins) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kOpen, 3);
  e.schedule_impulse(id, kStop, 3);  // validated after the queued open
  e.tick(), e.tick(), e.tick();
  const auto r = e.tick();
  ASSERT_EQ(r.applied.size(), 2u);
  EXPECT_EQ(r.applied[0].palette_index, kOpen);
  EXPECT_EQ(r.applied[1].palette_index, kStop);
  EXPECT_EQ(frame_of(r, id).palette_index, kStop);
}

TEST(Engine, ForbiddenTransitionsAreRefusedWithTheAllowedEntries) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kStop); }),
            "instance 1 (plate): 'stop' is not allowed from 'rest' (allowed: close, open)");
  e.schedule_impulse(id, kOpen);
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kClose); }),
            "instance 1 (plate): 'close' is not allowed after 'open' (allowed: stop)");
  e.tick();
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kOpen); }),
            "instance 1 (plate): 'open' is not allowed after 'open' (allowed: stop)");
}

TEST(Engine, ScheduledImpulseThatBecameForbiddenIsRefusedWhenItsFrameComes) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  e.schedule_impulse(id, kClose, 20);  // allowed from rest
  e.schedule_impulse(id, kOpen, 0);    // but the door is opening by frame 20
  TickResult r;
  for (int f = 0; f <= 20; ++f) r = e.tick();
  ASSERT_EQ(r.refused.size(), 1u);
  EXPECT_EQ(r.refused[0].frame, 20u);
  EXPECT_EQ(r.refused[0].error, "'close' is not allowed after 'open' (allowed: stop)");
  EXPECT_EQ(frame_of(r, id).palette_index, kOpen);
}

TEST(Engine, BadInputsAreRefusedWithOneLineMessages) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  e.tick();
  EXPECT_EQ(error_of<EngineError>([&] { e.create_instance("pot"); }),
            "unknown scene 'pot' (expected one of plate)");
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(7, kOpen); }),
            "unknown instance 7 (expected one of the 1 existing instances)");
  EXPECT_EQ(error_of<EngineError>([&] { e.palette_index(id, "opn"); }),
            "instance 1 (plate): unknown palette entry 'opn' (expected one of close, stop, open)");
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, 3); }),
            "instance 1 (plate): palette index 3 out of range (expected 0..2)");
  EXPECT_EQ(error_of<EngineError>([&] { e.schedule_impulse(id, kOpen, 0); }),
            "instance 1 (plate): frame 0 is in the past (expected at least the next frame 1)");
  EXPECT_EQ(error_of<EngineError>([&] { e.destroy_instance(9); }),
            "unknown instance 9 (expected one of the 1 existing instances)");
  EXPECT_EQ(error_of<EngineError>([&] { e.add_scene(default_plate(), "other.h5", 1); }),
            "scene 'plate' of other.h5 is already loaded from plate.h5 (expected unique scene names)");
  EXPECT_EQ(error_of<EngineError>([&] {
              SynthesisEngine x;
              x.add_scene(default_plate(), "p.h5", 1, NAN);
            }),
            "blend lambda nan for scene 'plate' (expected a finite value >= 0)");
  InstanceState broken;
  EXPECT_EQ(error_of<EngineError>([&] { e.restore_instance(5, "plate", 0, broken); }),
            "instance 5 (plate): inconsistent state (expected IRF, node and entry indices and offset sizes "
            "r_u = 4, r_a = " +
                std::to_string(default_plate()->rank_a()) + " of this scene)");
}

TEST(Engine, PendingImpulsesAreBounded) {
  auto e = engine_with(default_plate());
  const auto id = e.create_instance("plate");
  std::string err;
  for (std::uint64_t f = 0; f < 2000 && err.empty(); ++f) {
    err = error_of<EngineError>([&] { e.schedule_impulse(id, f % 2 ? kStop : kOpen, 2 * f); });
    if (err == "(no error)") err.clear();
  }
  EXPECT_EQ(err, "instance 1 (plate): 1024 impulses already pending (expected at most 1024 queued)");
}

// Runs a fixed schedule on three instances and returns every frame's bytes.
std::string run_schedule(const Package& pkg) {
  auto e = engine_with(pkg);
  for (int i = 0; i < 3; ++i) e.create_instance("plate");
  e.schedule_impulse(1, kOpen, 5);
  e.schedule_impulse(2, kOpen, 7);
  e.schedule_impulse(1, kStop, 40);
  e.schedule_impulse(3, kOpen, 0);
  std::string bytes;
  for (int f = 0; f < 400; ++f) {
    const auto r = e.tick();
    if (f == 120) e.schedule_impulse(2, kStop);  // the door is still opening: stop it
    if (f == 200) e.schedule_impulse(2, kClose);
    for (const auto& l : r.frames) {
      bytes.append(reinterpret_cast<const char*>(l.q_u.data()),
                   sizeof(float) * static_cast<size_t>(l.q_u.size()));
      bytes.append(reinterpret_cast<const char*>(l.q_a.data()),
                   sizeof(float) * static_cast<size_t>(l.q_a.size()));
      bytes.append(reinterpret_cast<const char*>(l.support.data()), sizeof(l.support));
      bytes.append(reinterpret_cast<const char*>(&l.irf), sizeof(l.irf));
    }
  }
  return bytes;
}

TEST(Engine, SameScheduleGivesBitIdenticalFrames) {
  const std::string a = run_schedule(default_plate());
  const std::string b = run_schedule(plate());  // a fresh copy of the same package
  ASSERT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b);
  testing::PlateOptions other;
  other.seed = 8;
  EXPECT_FALSE(a == run_schedule(plate(other))) << "a different package must change the stream";
}

TEST(Engine, RestoredInstanceContinuesExactly) {
  auto a = engine_with(default_plate());
  const auto id = a.create_instance("plate");
  a.schedule_impulse(id, kOpen);
  for (int f = 0; f < 25; ++f) a.tick();
  auto b = engine_with(default_plate());
  b.restore_instance(id, "plate", a.instance(id).frame, a.instance(id).state);
  for (int f = 0; f < 200; ++f) {
    const auto fa = tick_frame(a, id), fb = tick_frame(b, id);
    ASSERT_EQ(fa.frame, fb.frame);
    ASSERT_EQ(fa.q_u, fb.q_u);
    ASSERT_EQ(fa.q_a, fb.q_a);
    ASSERT_EQ(fa.support, fb.support);
  }
  EXPECT_EQ(b.create_instance("plate"), id + 1);
}

TEST(Engine, DestroyedInstanceStopsAndIdsAreNotReused) {
  auto e = engine_with(default_plate());
  const auto a = e.create_instance("plate");
  e.schedule_impulse(a, kOpen, 3);
  e.destroy_instance(a);
  EXPECT_TRUE(e.instances().empty());
  EXPECT_TRUE(e.tick().applied.empty());
  EXPECT_EQ(e.create_instance("plate"), a + 1);
}

// Every field, so a reused TickResult cannot leave a stale value behind.
void expect_same_frame(const SynthesizedFrame& a, const SynthesizedFrame& b) {
  EXPECT_EQ(a.instance, b.instance);
  EXPECT_EQ(a.scene, b.scene);
  EXPECT_EQ(a.frame, b.frame);
  ASSERT_EQ(a.q_u.size(), b.q_u.size());
  ASSERT_EQ(a.q_a.size(), b.q_a.size());
  EXPECT_EQ(a.q_u, b.q_u);
  EXPECT_EQ(a.q_a, b.q_a);
  EXPECT_EQ(a.support, b.support);
  EXPECT_EQ(a.palette_index, b.palette_index);
  EXPECT_EQ(a.irf, b.irf);
  EXPECT_EQ(a.irf_t, b.irf_t);
}

// Two scenes of different ranks, so a reused TickResult sees a slot change
// ranks when an instance goes and the ids shift down.
SynthesisEngine plate_and_tall() {
  testing::PlateOptions o;
  o.rank_u = 6;
  o.appearance = false;
  auto tall = testing::make_plate_package(o);
  tall.attributes.scene = "tall";
  auto e = engine_with(default_plate());
  e.add_scene(std::make_shared<const core::ScenePackage>(std::move(tall)), "tall.h5", 43);
  return e;
}

TEST(Engine, TickReturnsOneFrameForEachInstanceInIdOrderAlsoIntoAReusedResult) {
  auto fresh = plate_and_tall(), reused = plate_and_tall();
  TickResult into;
  auto step = [&] {
    const auto r = fresh.tick();
    reused.tick(into);
    ASSERT_EQ(r.frames.size(), fresh.instances().size());
    ASSERT_EQ(into.frames.size(), r.frames.size());
    auto inst = fresh.instances().begin();
    for (std::size_t i = 0; i < r.frames.size(); ++i, ++inst) {
      EXPECT_EQ(r.frames[i].instance, inst->first);
      EXPECT_EQ(r.frames[i].scene, inst->second.scene);
      EXPECT_EQ(r.frames[i].frame + 1, inst->second.frame) << "the frame just made";
      expect_same_frame(r.frames[i], into.frames[i]);
    }
    EXPECT_EQ(r.applied.size(), into.applied.size());
  };
  for (auto* e : {&fresh, &reused}) {
    e->create_instance("plate");
    e->create_instance("tall");
    e->create_instance("plate");
    e->schedule_impulse(1, kOpen);
  }
  for (int f = 0; f < 3; ++f) step();
  for (auto* e : {&fresh, &reused}) e->destroy_instance(1);
  step();  // slot 0 goes from plate (r_u = 4) to tall (r_u = 6, no appearance)
  for (auto* e : {&fresh, &reused}) e->create_instance("tall");
  step();
  EXPECT_EQ(into.frames.size(), 3u);
}

}  // namespace
}  // namespace phasecast::server
