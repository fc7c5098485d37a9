// The adaptive sampler's choice of where to direct its next chains
// (docs/sampling.md, "Adaptive sampling"): the worst guide segments first.

#include "phasecast/precompute/pipeline/adaptive_sampling.h"

#include <gtest/gtest.h>

namespace phasecast::precompute {
namespace {

SegmentFigures moving_segment(double motion_ratio, double nrmse, std::string refused = {},
                              bool unsampled = false) {
  SegmentFigures s;
  s.unsampled = unsampled;
  s.frames = 20;
  s.simulated_motion = 1e-3;
  s.motion_ratio = motion_ratio;
  s.nrmse = nrmse;
  s.refused = std::move(refused);
  return s;
}

// A schedule of four segments of entries 0..3; `bad` replaces segment `at`.
PlayedSchedule schedule_with(size_t at, const SegmentFigures& bad) {
  PlayedSchedule p;
  for (int k = 0; k < 4; ++k) {
    p.items.push_back({k, 0.4});
    p.figures.segments.push_back(moving_segment(1.0, 0.01));
  }
  p.figures.segments[at] = bad;
  return p;
}

TEST(AdaptiveSampling, MotionOutOfRangeComesBeforeNrmseAndRefusalsAreSkipped) {
  FidelityTarget target;
  target.median_nrmse = 0.15;
  const std::vector<PlayedSchedule> played{
      schedule_with(0, moving_segment(1.0, 0.6)),   // NRMSE 4x the target
      schedule_with(1, moving_segment(3.0, 0.05)),  // 3x the simulated motion
      schedule_with(2, moving_segment(1.0, 0.01)),  // plays well throughout
      schedule_with(2, moving_segment(0.0, 1.0, "'close' is not allowed after 'open'")),  // a rule's refusal
  };
  const auto lead_ins = directed_lead_ins(played, target, 4);
  // Each lead-in is its schedule up to and including the segment to sample.
  ASSERT_EQ(lead_ins.size(), 2u);
  EXPECT_EQ(lead_ins[0].size(), 2u);
  EXPECT_EQ(lead_ins[0].back().entry, 1);
  EXPECT_EQ(lead_ins[1].size(), 1u);
  EXPECT_EQ(directed_lead_ins(played, target, 1).size(), 1u);
}

TEST(AdaptiveSampling, WhileEntriesHaveNoIrfARoundSamplesOneChainOfEachAndNothingElse) {
  FidelityTarget target;
  target.median_nrmse = 0.15;
  const auto unsampled = moving_segment(0.0, 1.0, "no sampled IRF", true);
  // Entry 3 has no IRF in the second and third schedules, entry 1 only in the
  // fourth; the first schedule's motion is out of range.
  const std::vector<PlayedSchedule> played{schedule_with(0, moving_segment(3.0, 0.05)),
                                           schedule_with(3, unsampled), schedule_with(3, unsampled),
                                           schedule_with(1, unsampled)};
  const auto lead_ins = directed_lead_ins(played, target, 4);
  ASSERT_EQ(lead_ins.size(), 2u);
  EXPECT_EQ(lead_ins[0].back().entry, 3);
  EXPECT_EQ(lead_ins[0].size(), 4u);
  EXPECT_EQ(lead_ins[1].back().entry, 1);  // before entry 3's second segment
  EXPECT_EQ(lead_ins[1].size(), 2u);
  EXPECT_EQ(directed_lead_ins(played, target, 1).size(), 1u);
  // --directed-chains caps the rounds after coverage only: both entries get one.
  EXPECT_EQ(round_segments(played, target, 4, 1).size(), 2u);
}

// Ten guide schedules of four moving segments each, playing true but for
// `bad`, which replaces segment 0 of the first schedules, one each.
std::vector<PlayedSchedule> ten_schedules(const std::vector<std::pair<SegmentFigures, double>>& bad) {
  std::vector<PlayedSchedule> played;
  for (size_t k = 0; k < 10; ++k) {
    played.push_back(schedule_with(0, k < bad.size() ? bad[k].first : moving_segment(1.0, 0.01)));
    played.back().figures.nrmse = k < bad.size() ? bad[k].second : 0.01;
  }
  return played;
}

TEST(AdaptiveSampling, OnceEveryEntryHasIrfsARoundSamplesNoMoreChainsThanTheTargetLacks) {
  FidelityTarget target;  // median 0.15, 90th percentile 0.25, 95 % in range
  // Three of 40 moving segments out of range (one more than 95 % allows) and
  // three schedules above the median target, which the percentiles absorb.
  const auto out = moving_segment(3.0, 0.1), above = moving_segment(1.0, 0.2);
  const auto played =
      ten_schedules({{out, 0.1}, {out, 0.1}, {out, 0.1}, {above, 0.2}, {above, 0.2}, {above, 0.2}});
  EXPECT_EQ(target_shortfall(played, target), 1);
  ASSERT_EQ(directed_lead_ins(played, target, 4).size(), 1u);  // of six candidates
  // Three schedules at 0.5: the 90th percentile meets 0.25 once two of them do.
  const auto worse = moving_segment(1.0, 0.5);
  const auto tail = ten_schedules({{worse, 0.5}, {worse, 0.5}, {worse, 0.5}});
  EXPECT_EQ(target_shortfall(tail, target), 2);
  EXPECT_EQ(directed_lead_ins(tail, target, 4).size(), 2u);
  // --directed-chains 1 (the default) aims one of them a round; 0 both.
  EXPECT_EQ(round_segments(tail, target, 4, 1).size(), 1u);
  EXPECT_EQ(round_segments(tail, target, 4, 0).size(), 2u);
  EXPECT_EQ(target_shortfall(ten_schedules({{above, 0.2}}), target), 0);
}

// The guide schedules stay from round to round, so a segment a directed chain
// started from is judged again by the next round; a second chain from that
// state would sample the same IRF again, and goes to the next worst instead.
TEST(AdaptiveSampling, ASegmentThatHadADirectedChainIsNotChosenAgain) {
  FidelityTarget target;
  const auto out = moving_segment(3.0, 0.1), further = moving_segment(4.0, 0.1);
  auto played = ten_schedules({{further, 0.1}, {out, 0.1}, {out, 0.1}, {out, 0.1}});
  ASSERT_EQ(target_shortfall(played, target), 2);
  auto chosen = directed_segments(played, target, 4);
  ASSERT_EQ(chosen.size(), 2u);
  EXPECT_EQ(chosen[0].schedule, 0u);  // the furthest out of range
  EXPECT_EQ(chosen[1].schedule, 1u);
  played[0].directed = {true, false, false, false};
  chosen = directed_segments(played, target, 4);
  ASSERT_EQ(chosen.size(), 2u);
  EXPECT_EQ(chosen[0].schedule, 1u);
  EXPECT_EQ(chosen[1].schedule, 2u);
  for (auto& p : played) p.directed = {true, true, true, true};
  EXPECT_TRUE(directed_lead_ins(played, target, 4).empty());
}

TEST(AdaptiveSampling, MoreDirectedChainsThanChainsAreRejected) {
  SampleStageOptions first;
  first.sampling.chains = 4;
  first.sampling.irfs_per_chain = 2;
  AdaptiveOptions o;
  o.budget_irfs = 16;
  o.directed_chains = 4;
  EXPECT_NO_THROW(check_adaptive_options(o, first));
  o.directed_chains = 5;
  try {
    check_adaptive_options(o, first);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--directed-chains 5: expected at most --chains (4)"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace phasecast::precompute
