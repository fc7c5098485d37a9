// Palette rules from scene files, and the sampler's draws obeying them.

#include "phasecast/precompute/palette_rules.h"
#include "phasecast/precompute/irf_sampler.h"
#include "run_tool.h"
#include "scene_files.h"

#include <gtest/gtest.h>

#include <cmath>

namespace phasecast::precompute {
namespace {

using testing::edited_tiny_scene;
using testing::scratch_dir;
using testing::tiny_scene_path;

std::string error_of(const std::filesystem::path& scene) {
  try {
    make_palette_rules(load_scene(scene));
  } catch (const SceneError& e) {
    return e.what();
  }
  return "no error";
}

TEST(PaletteRules, DoorAllowsOnlyOmegaSteps) {
  const auto rules = make_palette_rules(load_scene(tiny_scene_path()));
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
      make_palette_rules(load_scene(edited_tiny_scene(dir, "after = [\"close\", \"open\"]\n", "")));
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
  EXPECT_NE(
      msg.find("palette entry 'stop': field 'on_end': unknown name 'halt' (expected close, stop, open)"),
      std::string::npos)
      << msg;
}

TEST(PaletteRules, TmaxBelowOneFrameAboveTminIsRejected) {
  const auto dir = scratch_dir("rules_tmax");
  const auto msg =
      error_of(edited_tiny_scene(dir, "t_min = 0.4\nt_max = 2.0", "t_min = 0.405\nt_max = 0.415"));
  EXPECT_NE(msg.find("palette entry 'stop': field 't_max': expected at least one frame"), std::string::npos)
      << msg;
}

TEST(PaletteRules, TminNotBelowTmaxIsRejectedByTheSceneParser) {
  const auto dir = scratch_dir("rules_tmin");
  try {
    load_scene(edited_tiny_scene(dir, "t_min = 0.4\nt_max = 2.0", "t_min = 3\nt_max = 2.0"));
    FAIL() << "expected a SceneError";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("t_min"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("below t_max"), std::string::npos) << e.what();
  }
}

TEST(IrfDraws, NeverViolateThePaletteRulesAndStayDeterministic) {
  const auto rules = make_palette_rules(load_scene(tiny_scene_path()));
  std::vector<int> used(3, 0);
  for (int chain = 0; chain < 20; ++chain) {
    int previous = -1;
    for (int irf = 0; irf < 50; ++irf) {
      const IrfDraw d = draw_irf(rules, 7, chain, irf, previous);
      ASSERT_TRUE(rules.allowed(d.from_rest ? -1 : previous, d.entry)) << previous << " -> " << d.entry;
      if (previous >= 0 && rules.on_end[static_cast<size_t>(previous)] >= 0) {
        ASSERT_EQ(d.entry, rules.on_end[static_cast<size_t>(previous)]);
      }
      ASSERT_GE(d.frames, rules.min_frames[static_cast<size_t>(d.entry)]);
      ASSERT_LE(d.frames, rules.max_frames[static_cast<size_t>(d.entry)]);
      const IrfDraw again = draw_irf(rules, 7, chain, irf, previous);
      ASSERT_EQ(again.entry, d.entry);
      ASSERT_EQ(again.frames, d.frames);
      ++used[static_cast<size_t>(d.entry)];
      previous = d.entry;
    }
  }
  for (int n : used) EXPECT_GT(n, 50);  // every entry gets sampled
  // A different seed gives a different sequence.
  int differ = 0;
  for (int irf = 0; irf < 20; ++irf)
    differ += draw_irf(rules, 7, 0, irf, 1).frames != draw_irf(rules, 8, 0, irf, 1).frames;
  EXPECT_GT(differ, 0);
}

}  // namespace
}  // namespace phasecast::precompute
