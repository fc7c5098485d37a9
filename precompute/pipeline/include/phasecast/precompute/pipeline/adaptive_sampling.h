#pragma once
// Sampling until the package plays true (§3.5; the paper's §7 asks for
// "better non-random sampling strategies for IRFs"). After a first round of
// random chains, each round reduces what was sampled, plays random guide
// schedules both through the full simulation and through the synthesis
// engine (validation), finds the segments where served motion departs from
// the simulated one, and spends its next IRFs there: one directed chain per
// segment, which plays the guide schedule from rest up to the item before
// that segment (simulated, not recorded), records that item and the
// segment's entry from the very state where the served playback went wrong
// (kRecordedLeadIns), and then draws on as any chain. The guide schedules are
// drawn once, from their own stream (never the sampler's, never the held-out
// schedules that measure the result: measure_fidelity with another seed),
// and simulated once: every round plays its package against the same truths,
// so a round is judged on the segments the previous one directed its chains
// at, and costs no simulation beyond its chains (and any fresh schedules,
// below). That makes the guide figures optimistic, so when they meet the
// target, the same package plays fresh schedules (no chain was aimed at
// them), which then join the guides: rounds stop when the fresh ones meet
// the target too, or when the budget is spent.

#include "phasecast/core/package.h"
#include "phasecast/precompute/pipeline/stages.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/validation/playback.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::precompute {

// What a package must play at: median and 90th-percentile NRMSE over random
// schedules, and the share of moving segments whose motion is within
// [0.67, 1.5] of the simulated motion (docs/validation.md).
struct FidelityTarget {
  double median_nrmse = 0.15;
  double p90_nrmse = 0.25;
  double moving_in_range = 0.95;
};

// A package played against the full simulation over random schedules.
struct FidelityFigures {
  int schedules = 0;
  std::uint64_t seed = 0;  // of random_schedule
  int items = 0;           // entries per schedule
  double median_nrmse = 0, p90_nrmse = 0;
  int moving = 0, moving_within = 0;
  int switches = 0, switches_within = 0;  // blend jumps within 2x the local motion

  double moving_in_range() const { return moving ? static_cast<double>(moving_within) / moving : 1.0; }
  bool meets(const FidelityTarget& t) const {
    return median_nrmse <= t.median_nrmse && p90_nrmse <= t.p90_nrmse &&
           moving_in_range() >= t.moving_in_range;
  }
};

// A guide schedule as a round's package played it.
struct PlayedSchedule {
  std::vector<ScheduleItem> items;
  ScheduleFigures figures;
  // Per segment (or empty): a directed chain of an earlier round started
  // from it. The guide schedules stay, and a second chain from the same
  // state would sample the same IRF again, so it is not chosen again.
  std::vector<bool> directed;
};

// Plays `schedules` random schedules of `items` entries (random_schedule with
// `seed`) both ways; `progress` hears schedules done / total (each is a full
// simulation: minutes on a large scene).
FidelityFigures measure_fidelity(const Scene& scene, const core::ScenePackage& package, std::uint64_t seed,
                                 int schedules, int items, const ProgressCallback& progress = {});

struct AdaptiveOptions {
  FidelityTarget target;
  int budget_irfs = 0;          // all IRFs sampled, the first round's included (0: no limit but the time)
  double budget_minutes = 0;    // wall time of the rounds (0: no limit but the IRFs)
  int guide_schedules = 20;     // random schedules, drawn once, every round is judged on (docs/sampling.md)
  int fresh_schedules = 20;     // drawn to check the guides each time they meet the target (0: none)
  int schedule_items = 4;       // entries per guide schedule
  int directed_chains = 1;      // per round once every entry has IRFs, <= first's chains (0: as many)
  int directed_extra_irfs = 2;  // IRFs a directed chain draws after its kRecordedLeadIns
};

// The segments the next round's directed chains start from, at most
// `count`. While some entry has no IRF: one segment of each such entry and
// nothing else. Otherwise the guide schedules' worst moving segments: motion
// ratio out of [0.67, 1.5], by |log ratio|, then NRMSE above the target;
// none for a segment that plays within the target or was directed at before;
// and no more of them than the guide figures fall short of the target by
// (target_shortfall).
struct GuideSegment {
  size_t schedule = 0, segment = 0;
};
std::vector<GuideSegment> directed_segments(const std::vector<PlayedSchedule>& played,
                                            const FidelityTarget& target, int count);
// A round's segments: directed_segments' up to `chains`, and once every entry
// has IRFs at most `directed_chains` of them (0: no further cap).
std::vector<GuideSegment> round_segments(const std::vector<PlayedSchedule>& played,
                                         const FidelityTarget& target, int chains, int directed_chains);
// The same as lead-ins: each the schedule's items up to and through its segment.
std::vector<std::vector<ScheduleItem>> directed_lead_ins(const std::vector<PlayedSchedule>& played,
                                                         const FidelityTarget& target, int count);

// How many guide schedules or segments keep `played` from the target, each
// of which a directed chain mends at best: the moving segments out of range
// beyond the share the target allows, or the fewest worst schedules whose
// NRMSE must come down for the median and the 90th percentile to meet it,
// whichever is more. 0 when the figures meet the target.
int target_shortfall(const std::vector<PlayedSchedule>& played, const FidelityTarget& target);

struct AdaptiveRound {
  int irfs = 0;           // sampled in all, this round's included
  int directed = 0;       // directed chains this round added (0 for the first)
  FidelityFigures guide;  // the package of all IRFs so far, on the guide schedules
  // When `guide` met the target: the same package on `fresh` schedules drawn
  // then (AdaptiveOptions::fresh_schedules; the guides from then on).
  int fresh = 0;
  FidelityFigures fresh_figures;
};

struct AdaptiveReport {
  bool writer = false;  // rank 0: the one that reports
  std::vector<AdaptiveRound> rounds;
  bool met = false;
  std::string stopped;   // why the rounds ended: "target met", "IRF budget spent", ...
  SampleReport sampled;  // the merged store of every round
};

// Samples `first` (the first round) into `orbits`, then adds directed rounds
// as above. The merged store of every round's chains ends in `orbits`; each
// round's chains and its package go to <work folder>/round-<r>/.
AdaptiveReport run_adaptive_sampling(const Scene& scene, const SampleStageOptions& first,
                                     const ReduceStageOptions& reduce, const AdaptiveOptions& options,
                                     const std::filesystem::path& orbits);

// "fidelity (held-out, 20 random schedules of 4 entries, seed S): median NRMSE ..., 90th ..., ..."
std::string fidelity_text(const FidelityFigures& figures, const char* which);

// One line per round (its IRFs and guide figures; a second with the fresh
// schedules' where it played them), then why the rounds ended.
std::string adaptive_report_text(const AdaptiveReport& report);

// Throws std::invalid_argument naming the flag of an impossible option.
void check_adaptive_options(const AdaptiveOptions& options, const SampleStageOptions& first);

}  // namespace phasecast::precompute
