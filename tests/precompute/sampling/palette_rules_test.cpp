// Palette rules from scene files, and the sampler's draws obeying them.

#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/sampling/irf_sampler.h"
#include "run_tool.h"
#include "scene_files.h"

#include <gtest/gtest.h>

#include <numbers>

#include <cmath>
#include <fstream>

namespace phasecast::precompute {
namespace {

using testing::edited_tiny_scene;
using testing::scratch_dir;
using testing::tiny_scene_path;

std::string error_of(const std::filesystem::path& scene) {
  try {
    make_palette_rules(load_scene_file(scene));
  } catch (const SceneError& e) {
    return e.what();
  }
  return "no error";
}

TEST(PaletteRules, DoorAllowsOnlyOmegaSteps) {
  const auto rules = make_palette_rules(load_scene_file(tiny_scene_path()));
  const int close = 0, stop = 1, open = 2;
  ASSERT_EQ(rules.size(), 3);
  EXPECT_EQ(rules.successors(-1), (std::vector<int>{close, open}));
  EXPECT_EQ(rules.successors(close), (std::vector<int>{stop}));
  EXPECT_EQ(rules.successors(stop), (std::vector<int>{close, open}));
  EXPECT_EQ(rules.successors(open), (std::vector<int>{stop}));
  EXPECT_FALSE(rules.allowed(open, close));
  EXPECT_FALSE(rules.allowed(close, open));
  EXPECT_EQ(rules.on_end, (std::vector<std::int32_t>{stop, core::kEndRest, stop}));
  // Door IRFs last at most 90 deg / |w0| = 1.047 s = 52 frames of 20 ms; at least 0.2 s.
  EXPECT_EQ(rules.max_frames[close], 52);
  EXPECT_EQ(rules.min_frames[open], 10);
  EXPECT_EQ(rules.transitions.rows(), 4);
  EXPECT_EQ(rules.transitions.cols(), 3);
}

TEST(PaletteRules, EntryWithoutAfterMayFollowAnything) {
  const auto dir = scratch_dir("rules_no_after");
  const auto rules =
      make_palette_rules(load_scene_file(edited_tiny_scene(dir, "after = [\"close\", \"open\"]\n", "")));
  EXPECT_EQ(rules.transitions.col(1).sum(), 4);
}

TEST(PaletteRules, UnknownNameInAfterIsRejectedWithTheKnownNames) {
  const auto dir = scratch_dir("rules_unknown_after");
  const auto msg =
      error_of(edited_tiny_scene(dir, "after = [\"close\", \"open\"]", "after = [\"close\", \"opn\"]"));
  EXPECT_NE(
      msg.find("palette entry 'stop': field 'after': unknown name 'opn' (expected rest, close, stop, open)"),
      std::string::npos)
      << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos);
}

TEST(PaletteRules, FollowUpMustBeAllowedAfterItsEntry) {
  const auto dir = scratch_dir("rules_follow_up");
  const auto msg = error_of(edited_tiny_scene(dir, "after = [\"close\", \"open\"]", "after = [\"open\"]"));
  EXPECT_NE(
      msg.find("palette entry 'close': field 'on_end': follow-up 'stop' must list 'close' in its 'after'"),
      std::string::npos)
      << msg;
}

TEST(PaletteRules, UnknownFollowUpIsRejected) {
  const auto dir = scratch_dir("rules_unknown_on_end");
  const auto msg = error_of(edited_tiny_scene(dir, "on_end = \"rest\"", "on_end = \"halt\""));
  EXPECT_NE(msg.find("palette entry 'stop': field 'on_end': unknown name 'halt' (expected rest, hold, close, "
                     "stop, open)"),
            std::string::npos)
      << msg;
}

TEST(PaletteRules, TmaxBelowOneFrameAboveTminIsRejected) {
  const auto dir = scratch_dir("rules_tmax");
  const auto msg =
      error_of(edited_tiny_scene(dir, "t_min = 2.4\nt_max = 3.0", "t_min = 2.405\nt_max = 2.415"));
  EXPECT_NE(msg.find("palette entry 'stop': field 't_max': expected at least one frame"), std::string::npos)
      << msg;
}

TEST(PaletteRules, TminNotBelowTmaxIsRejectedByTheSceneParser) {
  const auto dir = scratch_dir("rules_tmin");
  try {
    load_scene_file(edited_tiny_scene(dir, "t_min = 2.4\nt_max = 3.0", "t_min = 4\nt_max = 3.0"));
    FAIL() << "expected a SceneError";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("t_min"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("below t_max"), std::string::npos) << e.what();
  }
}

// Draws `irfs` IRFs of one chain as the sampler does (the support coordinate
// advanced kinematically), checking every rule on the way, the support's
// range included; returns the entries and, in `stops`, the door angle at
// which each IRF holding the support still began.
std::vector<int> checked_chain(const PaletteRules& rules, std::uint64_t seed, int chain, int irfs,
                               std::vector<double>* stops = nullptr) {
  std::vector<int> history, entries;
  double at = 0;
  for (int irf = 0; irf < irfs; ++irf) {
    const IrfDraw d = draw_irf(rules, seed, chain, irf, history, at);
    if (d.from_rest) history.clear(), at = 0;
    const auto e = static_cast<size_t>(d.entry);
    EXPECT_TRUE(rules.allowed_after(history, d.entry)) << "chain " << chain << " IRF " << irf;
    if (!history.empty() && rules.on_end[static_cast<size_t>(history.back())] >= 0 &&
        rules.allowed_at(history, rules.on_end[static_cast<size_t>(history.back())], at)) {
      EXPECT_EQ(d.entry, rules.on_end[static_cast<size_t>(history.back())]);
    }
    // §3.5: never an IRF whose support cannot move, never past the range's end.
    const int reach = rules.reachable_frames(d.entry, at);
    EXPECT_GE(reach, 1) << "chain " << chain << " IRF " << irf << ": entry " << d.entry << " at " << at;
    EXPECT_LE(d.frames, reach);
    EXPECT_GE(d.frames, std::min(rules.min_frames[e], reach));
    EXPECT_LE(d.frames, rules.max_frames[e]);
    const IrfDraw again = draw_irf(rules, seed, chain, irf, history, at);
    EXPECT_EQ(again.entry, d.entry);
    EXPECT_EQ(again.frames, d.frames);
    if (stops && rules.support_rate[e] == 0) stops->push_back(at);
    history.push_back(d.entry);
    entries.push_back(d.entry);
    at = rules.advance(d.entry, at, d.frames);
    EXPECT_GE(at, rules.range_min - 1e-9);
    EXPECT_LE(at, rules.range_max + 1e-9);
  }
  return entries;
}

TEST(IrfDraws, TheDoorIsNeverDrivenIntoItsStopsAndIsReachedAtEveryAngle) {
  const auto rules = make_palette_rules(load_scene_file(tiny_scene_path()));
  ASSERT_NEAR(rules.range_max, std::numbers::pi / 2, 1e-9);
  std::vector<double> stops;
  for (int chain = 0; chain < 20; ++chain) checked_chain(rules, 3, chain, 30, &stops);
  // The door stops at angles spread over its range: every 15-degree band is visited.
  std::vector<int> band(6, 0);
  for (double a : stops) ++band[static_cast<size_t>(std::min(5.0, a / (std::numbers::pi / 12)))];
  for (size_t b = 0; b < band.size(); ++b) EXPECT_GT(band[b], 0) << "band " << b;
  // At the closed stop, closing is never drawn; at the open stop, opening is not.
  const int close = 0, open = 2;
  EXPECT_EQ(rules.reachable_frames(close, 0.0), 0);
  EXPECT_EQ(rules.reachable_frames(open, rules.range_max), 0);
  EXPECT_FALSE(rules.allowed_at({}, close, 0.0));
}

TEST(IrfDraws, NeverViolateThePaletteRulesAndStayDeterministic) {
  const auto rules = make_palette_rules(load_scene_file(tiny_scene_path()));
  std::vector<int> used(3, 0);
  for (int chain = 0; chain < 20; ++chain) {
    for (int e : checked_chain(rules, 7, chain, 50)) ++used[static_cast<size_t>(e)];
  }
  for (int n : used) EXPECT_GT(n, 50);  // every entry gets sampled
  // A different seed gives a different sequence.
  int differ = 0;
  for (int irf = 0; irf < 20; ++irf)
    differ += draw_irf(rules, 7, 0, irf, {1}).frames != draw_irf(rules, 8, 0, irf, {1}).frames;
  EXPECT_GT(differ, 0);
}

TEST(IrfDraws, MaxInARowLimitsRunsOfAGroup) {
  // Let stop follow itself, at most twice in a row; close and open form one group of at most one.
  const auto dir = scratch_dir("rules_in_a_row");
  std::string text = testing::read_file(tiny_scene_path());
  const auto replace = [&](const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  };
  replace("after = [\"close\", \"open\"]", "after = [\"close\", \"open\", \"stop\"]\nmax_in_a_row = 2");
  replace("on_end = \"stop\"               # the door stops",
          "group = \"swing\"\nmax_in_a_row = 1\non_end = \"stop\" #");
  replace("after = [\"rest\", \"stop\"]\nt_min = 0.2\nt_max = 1.0472\non_end = \"stop\"",
          "after = [\"rest\", \"stop\"]\nt_min = 0.2\nt_max = 1.0472\ngroup = \"swing\"\non_end = \"stop\"");
  std::ofstream(dir / "scene.toml") << text;
  const auto rules = make_palette_rules(load_scene_file(dir / "scene.toml"));
  EXPECT_EQ(rules.group[0], rules.group[2]);
  EXPECT_NE(rules.group[0], rules.group[1]);
  EXPECT_FALSE(rules.allowed_after({1, 1}, 1));
  EXPECT_TRUE(rules.allowed_after({0, 1}, 1));
  int double_stops = 0;
  for (int chain = 0; chain < 10; ++chain) {
    const auto entries = checked_chain(rules, 3, chain, 60);
    for (size_t i = 2; i < entries.size(); ++i) {
      EXPECT_FALSE(entries[i] == 1 && entries[i - 1] == 1 && entries[i - 2] == 1) << "three stops in a row";
    }
    for (size_t i = 1; i < entries.size(); ++i) double_stops += entries[i] == 1 && entries[i - 1] == 1;
  }
  EXPECT_GT(double_stops, 0);  // the limit binds: two in a row do occur
}

TEST(PaletteRules, NegativeMaxInARowIsRejected) {
  const auto dir = scratch_dir("rules_bad_in_a_row");
  try {
    load_scene_file(edited_tiny_scene(dir, "t_min = 2.4\n", "t_min = 2.4\nmax_in_a_row = -1\n"));
    FAIL() << "expected a SceneError";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("max_in_a_row"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("a whole number >= 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace phasecast::precompute
