// Adaptive sampling (adaptive_sampling.h): rounds of directed chains where
// validation finds the served motion departing from the simulation.

#include "phasecast/precompute/pipeline/adaptive_sampling.h"

#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/validation/playback.h"
#include "stopwatch.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <compare>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

// SplitMix64 of the run's seed and a purpose: the guide schedules and each
// round's directed chains get streams of their own.
std::uint64_t stream(std::uint64_t seed, std::uint64_t purpose) {
  std::uint64_t x = seed ^ (purpose * 0x9e3779b97f4a7c15ULL);
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

constexpr std::uint64_t kGuide = 0x6775696465ULL;         // "guide"
constexpr std::uint64_t kDirected = 0x6469726563ULL;      // "direc"
constexpr size_t kKeptGuideTruthBytes = size_t{1} << 30;  // per rank

// How far a segment plays from the target, compared tier first: an entry
// the package has no IRF of (the server refused it: nothing of it plays),
// then out of the motion range by |log ratio|, then NRMSE above the median
// target by how much. {0, 0} when it plays within both, and for segments
// refused by a palette rule, which a chain of that entry cannot mend.
struct Badness {
  int tier = 0;  // 2 no IRF of the entry, 1 motion out of range, 0 NRMSE
  double amount = 0;
  auto operator<=>(const Badness&) const = default;
  bool any() const { return tier > 0 || amount > 0; }
};

Badness badness(const SegmentFigures& s, double typical, const FidelityTarget& t) {
  if (s.unsampled) return {2, 0};
  if (!s.refused.empty() || !is_moving(s, typical)) return {};
  if (s.motion_ratio < kMotionLow || s.motion_ratio > kMotionHigh)
    return {1, std::abs(std::log(std::max(s.motion_ratio, 1e-6)))};
  return {0, s.nrmse > t.median_nrmse ? s.nrmse / t.median_nrmse - 1 : 0};
}

// A guide segment a directed chain may start from.
struct Candidate {
  Badness badness;
  size_t schedule, segment;
};

// While entries have no IRF, a round samples one chain per such entry and
// nothing else: the server refuses them, so every segment after one plays
// from a state the simulation never reaches, and its figures say little about
// where else IRFs are wanted until the next round judges the mended package.
void only_one_chain_per_unsampled_entry(std::vector<Candidate>& sorted,
                                        const std::vector<PlayedSchedule>& played) {
  if (sorted.empty() || sorted.front().badness.tier != 2) return;
  std::vector<Candidate> firsts;
  std::set<int> entries;
  for (const auto& c : sorted)
    if (c.badness.tier == 2 && entries.insert(played[c.schedule].items[c.segment].entry).second)
      firsts.push_back(c);
  sorted = std::move(firsts);
}

int irfs_of(const SampleStageOptions& round) {
  return round.sampling.chains * round.sampling.irfs_per_chain;
}

bool unsampled(const std::vector<PlayedSchedule>& played, const GuideSegment& s) {
  return played[s.schedule].figures.segments[s.segment].unsampled;
}

// The guide schedule's items up to and through the segment.
std::vector<ScheduleItem> lead_in(const std::vector<PlayedSchedule>& played, const GuideSegment& s) {
  const auto& items = played[s.schedule].items;
  return {items.begin(), items.begin() + static_cast<std::ptrdiff_t>(s.segment + 1)};
}

// The round after `round_index` judged `played`: its directed chains, at most
// --chains (--directed-chains once every entry has IRFs) and as many as the
// budget allows. Marks the segments they start from in
// `directed`, which the guide schedules keep from round to round.
std::optional<SampleStageOptions> next_round(const SampleStageOptions& first, const AdaptiveOptions& o,
                                             const std::vector<PlayedSchedule>& played,
                                             std::vector<std::vector<bool>>& directed, int round_index,
                                             int irfs_so_far, const std::filesystem::path& work) {
  auto segments = round_segments(played, o.target, first.sampling.chains, o.directed_chains);
  // Every chain of a round samples as many IRFs: the item before the segment
  // and the segment's (kRecordedLeadIns; the lead-in before them is simulated,
  // not recorded), then random ones; a schedule's first segment draws one more
  // random IRF instead. What does not fit the budget goes: random IRFs first,
  // then chains.
  int extra = o.directed_extra_irfs;
  const auto cost = [&](size_t n) {
    return static_cast<int>(n) * (static_cast<int>(kRecordedLeadIns) + extra);
  };
  const auto over = [&] { return o.budget_irfs > 0 && irfs_so_far + cost(segments.size()) > o.budget_irfs; };
  while (!segments.empty() && over()) {
    if (extra > 0) {
      --extra;
    } else {
      segments.pop_back();
      extra = o.directed_extra_irfs;
    }
  }
  if (segments.empty()) return std::nullopt;
  SampleStageOptions next = first;
  next.sampling.chains = static_cast<int>(segments.size());
  next.sampling.irfs_per_chain = cost(segments.size()) / next.sampling.chains;
  next.sampling.seed = stream(first.sampling.seed, kDirected + static_cast<std::uint64_t>(round_index));
  for (const auto& s : segments) {
    next.sampling.lead_ins.push_back(lead_in(played, s));
    directed[s.schedule][s.segment] = true;
  }
  next.work_dir = work / fmt::format("round-{}", round_index + 1);
  return next;
}

FidelityFigures figures_of(const ValidationSummary& summary, std::uint64_t seed, int items) {
  FidelityFigures f;
  f.schedules = static_cast<int>(summary.nrmse.size());
  f.seed = seed;
  f.items = items;
  f.median_nrmse = summary.median_nrmse();
  f.p90_nrmse = summary.p90_nrmse();
  f.moving = summary.moving;
  f.moving_within = summary.moving_within;
  f.switches = summary.switches;
  f.switches_within = summary.switches_within;
  return f;
}

// Random schedules drawn once and played against one package or several,
// each simulated once while their truths fit `kept_truth_bytes` on this rank
// (the rest are simulated again at each play, to the same frames). The guide
// schedules of every round are one such set, so a round is judged on the
// schedules whose segments the previous round's chains were directed at.
class RandomSchedules {
 public:
  RandomSchedules(const Scene& scene, std::uint64_t seed, int schedules, int items, size_t kept_truth_bytes)
      : scene_(scene),
        rules_(make_palette_rules(scene)),
        seed_(seed),
        items_(items),
        kept_truth_bytes_(kept_truth_bytes) {
    draw(schedules);
  }

  // Draws `count` more schedules of the same stream (random_schedule's next
  // indices); returns how many were not empty (an empty one is skipped).
  int draw(int count) {
    const size_t before = schedules_.size();
    for (int k = 0; k < count; ++k, ++drawn_) {
      auto drawn = random_schedule(rules_, scene_.simulation.frame_dt, seed_, drawn_, items_);
      if (drawn.empty()) continue;
      directed_.emplace_back(drawn.size(), false);
      schedules_.push_back(std::move(drawn));
    }
    truths_.resize(schedules_.size());
    return static_cast<int>(schedules_.size() - before);
  }

  // Segments that had a directed chain: a second from the same state would sample the same IRF.
  std::vector<std::vector<bool>>& directed() { return directed_; }

  // Plays the schedules `played` lacks (all of them into an empty one; the
  // ones drawn since, where `package` played the others) and returns their
  // figures.
  FidelityFigures play(const core::ScenePackage& package, std::vector<PlayedSchedule>& played,
                       const ProgressCallback& progress) {
    check_package_of(scene_, package);
    const auto shared = std::make_shared<const core::ScenePackage>(package);
    ValidationOptions options;
    options.intersections = false;
    ValidationSummary summary;
    const size_t start = played.size();
    for (size_t k = start; k < schedules_.size(); ++k) {
      SimulatedSchedule unkept;
      PlayedSchedule p{schedules_[k], compare_playback(scene_, shared, truth(k, unkept), options),
                       directed_[k]};
      summary.add(p.figures);
      played.push_back(std::move(p));
      if (progress) progress(static_cast<int>(k + 1 - start), static_cast<int>(schedules_.size() - start));
    }
    return figures_of(summary, seed_, items_);
  }

 private:
  // Schedule k's truth: the kept one, or simulated now and kept if it fits,
  // else left in `unkept`, which the caller drops after this round's playback.
  const SimulatedSchedule& truth(size_t k, SimulatedSchedule& unkept) {
    if (truths_[k]) return *truths_[k];
    unkept = simulate_truth(scene_, schedules_[k]);
    const auto bytes = static_cast<size_t>(unkept.frames.size()) * sizeof(double);
    if (kept_bytes_ + bytes > kept_truth_bytes_) return unkept;
    kept_bytes_ += bytes;
    truths_[k] = std::move(unkept);
    return *truths_[k];
  }

  const Scene& scene_;
  PaletteRules rules_;
  std::uint64_t seed_;
  int items_;
  int drawn_ = 0;  // random_schedule indices used
  size_t kept_truth_bytes_;
  std::vector<std::vector<ScheduleItem>> schedules_;
  std::vector<std::optional<SimulatedSchedule>> truths_;
  std::vector<std::vector<bool>> directed_;
  size_t kept_bytes_ = 0;
};

// Plays the guide schedules `played` lacks with a progress bar named `what`.
FidelityFigures play_guides(RandomSchedules& guides, const core::ScenePackage& package,
                            std::vector<PlayedSchedule>& played, const std::string& what) {
  core::ProgressBar bar{what};
  auto figures = guides.play(package, played, [&bar](int done, int total) { bar.update(done, total); });
  bar.finish();
  return figures;
}

// "adaptive round 2: 48 IRFs, 20 fresh guide schedules: median NRMSE ..."
std::string round_line(int r, int irfs, const char* which, const FidelityFigures& f) {
  return fmt::format(
      "adaptive round {}: {} IRFs, {} {}guide schedules: median NRMSE {:.3f}, 90th {:.3f}, {:.0f} % of "
      "moving segments in range\n",
      r, irfs, f.schedules, which, f.median_nrmse, f.p90_nrmse, 100 * f.moving_in_range());
}

// Plays round r's package on the guide schedules into `played` and, when
// they meet the target, draws fresh ones, which join the guides, and plays
// those too: no chain was aimed at them, so their figures alone check the
// guides' (judged together, the guides' optimism would pass them).
void judge_round(RandomSchedules& guides, const core::ScenePackage& package, const AdaptiveOptions& o, int r,
                 bool writer, AdaptiveRound& round, std::vector<PlayedSchedule>& played) {
  round.guide = play_guides(guides, package, played, fmt::format("round {} guide schedules", r));
  if (writer) fmt::print(stderr, "{}", round_line(r, round.irfs, "", round.guide));
  if (!round.guide.meets(o.target) || o.fresh_schedules == 0) return;
  round.fresh = guides.draw(o.fresh_schedules);
  if (round.fresh == 0) return;  // the palette rules gave only empty schedules: the guides' figures stand
  round.fresh_figures =
      play_guides(guides, package, played, fmt::format("round {} fresh guide schedules", r));
  if (writer) fmt::print(stderr, "{}", round_line(r, round.irfs, "fresh ", round.fresh_figures));
}

}  // namespace

FidelityFigures measure_fidelity(const Scene& scene, const core::ScenePackage& package, std::uint64_t seed,
                                 int schedules, int items, const ProgressCallback& progress) {
  std::vector<PlayedSchedule> played;
  return RandomSchedules(scene, seed, schedules, items, 0).play(package, played, progress);
}

std::vector<GuideSegment> directed_segments(const std::vector<PlayedSchedule>& played,
                                            const FidelityTarget& target, int count) {
  std::vector<Candidate> candidates;
  for (size_t i = 0; i < played.size(); ++i) {
    const auto& g = played[i].figures;
    const double typical = typical_motion(g);
    for (size_t m = 0; m < g.segments.size() && m < played[i].items.size(); ++m) {
      if (m < played[i].directed.size() && played[i].directed[m]) continue;
      const Badness b = badness(g.segments[m], typical, target);
      if (b.any()) candidates.push_back({b, i, m});
    }
  }
  // The worst first; equals in schedule and segment order (stable), so every rank picks alike.
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.badness > b.badness; });
  only_one_chain_per_unsampled_entry(candidates, played);
  if (!candidates.empty() && candidates.front().badness.tier != 2)
    count = std::min(count, std::max(1, target_shortfall(played, target)));
  std::vector<GuideSegment> out;
  for (const auto& c : candidates) {
    if (static_cast<int>(out.size()) >= count) break;
    out.push_back({c.schedule, c.segment});
  }
  return out;
}

std::vector<GuideSegment> round_segments(const std::vector<PlayedSchedule>& played,
                                         const FidelityTarget& target, int chains, int directed_chains) {
  auto segments = directed_segments(played, target, chains);
  // Once every entry has IRFs, a round adds at most directed_chains: the guide
  // schedules are kept, so the next round judges what each one mended before
  // more go. A round that covers entries without IRFs is not capped.
  if (directed_chains > 0 && !segments.empty() && !unsampled(played, segments.front()) &&
      static_cast<int>(segments.size()) > directed_chains)
    segments.resize(static_cast<size_t>(directed_chains));
  return segments;
}

std::vector<std::vector<ScheduleItem>> directed_lead_ins(const std::vector<PlayedSchedule>& played,
                                                         const FidelityTarget& target, int count) {
  std::vector<std::vector<ScheduleItem>> out;
  for (const auto& s : directed_segments(played, target, count)) out.push_back(lead_in(played, s));
  return out;
}

int target_shortfall(const std::vector<PlayedSchedule>& played, const FidelityTarget& target) {
  ValidationSummary s;
  for (const auto& p : played) s.add(p.figures);
  const int out_of_range =
      static_cast<int>(std::ceil(target.moving_in_range * s.moving - 1e-9)) - s.moving_within;
  std::sort(s.nrmse.begin(), s.nrmse.end(), std::greater<>());
  int schedules = 0;
  while (schedules < static_cast<int>(s.nrmse.size()) &&
         (s.median_nrmse() > target.median_nrmse || s.p90_nrmse() > target.p90_nrmse))
    s.nrmse[static_cast<size_t>(schedules++)] = 0;  // as if that schedule played true
  return std::max(out_of_range, schedules);
}

std::string fidelity_text(const FidelityFigures& f, const char* which) {
  return fmt::format(
      "fidelity ({}, {} random schedules of {} entries, seed {}): median NRMSE {:.3f}, 90th percentile "
      "{:.3f}, "
      "{} of {} moving segments ({:.0f} %) within [0.67, 1.5] of the simulated motion, {} of {} switches "
      "within 2x the local motion\n",
      which, f.schedules, f.items, f.seed, f.median_nrmse, f.p90_nrmse, f.moving_within, f.moving,
      100 * f.moving_in_range(), f.switches_within, f.switches);
}

std::string adaptive_report_text(const AdaptiveReport& a) {
  std::string out;
  for (size_t r = 0; r < a.rounds.size(); ++r) {
    const auto& round = a.rounds[r];
    out += fmt::format("adaptive round {}: {} IRFs{}; ", r, round.irfs,
                       round.directed ? fmt::format(" ({} directed chain{} added)", round.directed,
                                                    round.directed == 1 ? "" : "s")
                                      : "");
    out += fidelity_text(round.guide, "guide");
    if (round.fresh)
      out += fmt::format("adaptive round {}, on fresh schedules: ", r) +
             fidelity_text(round.fresh_figures, "fresh");
  }
  out += fmt::format("adaptive sampling: {} after {} rounds, {} IRFs\n", a.stopped, a.rounds.size(),
                     a.rounds.empty() ? 0 : a.rounds.back().irfs);
  return out;
}

void check_adaptive_options(const AdaptiveOptions& o, const SampleStageOptions& first) {
  const FidelityTarget& t = o.target;
  if (!(t.median_nrmse > 0) || !(t.p90_nrmse >= t.median_nrmse) || !(t.moving_in_range >= 0) ||
      !(t.moving_in_range <= 1))
    throw std::invalid_argument(fmt::format(
        "--until-fidelity {}: expected a median NRMSE > 0 (the 90th percentile {} at least that, the share "
        "in range {} in [0, 1])",
        t.median_nrmse, t.p90_nrmse, t.moving_in_range));
  if (o.budget_irfs <= 0 && !(o.budget_minutes > 0))
    throw std::invalid_argument("--until-fidelity needs a budget: --budget-irfs N or --budget-minutes M");
  if (o.budget_irfs > 0 && o.budget_irfs < irfs_of(first))
    throw std::invalid_argument(fmt::format(
        "--budget-irfs {}: expected at least the first round's {} IRFs (--chains x --irfs-per-chain)",
        o.budget_irfs, irfs_of(first)));
  if (o.guide_schedules < 1 || o.schedule_items < 1 || o.fresh_schedules < 0 || o.directed_chains < 0 ||
      o.directed_extra_irfs < 0)
    throw std::invalid_argument(
        "adaptive sampling: expected --guide-schedules and items >= 1, --fresh-schedules, --directed-chains "
        "and --directed-extra-irfs >= 0");
  // A round aims at most --chains segments (directed_segments' count).
  if (o.directed_chains > first.sampling.chains)
    throw std::invalid_argument(
        fmt::format("--directed-chains {}: expected at most --chains ({}), the most "
                    "chains a round adds",
                    o.directed_chains, first.sampling.chains));
}

AdaptiveReport run_adaptive_sampling(const Scene& scene, const SampleStageOptions& first,
                                     const ReduceStageOptions& reduce, const AdaptiveOptions& o,
                                     const std::filesystem::path& orbits) {
  check_adaptive_options(o, first);
  const Stopwatch clock;
  const std::filesystem::path work =
      first.work_dir.empty() ? std::filesystem::path(orbits.string() + ".work") : first.work_dir;
  std::vector<SampleStageOptions> rounds{first};
  rounds.front().work_dir = work;
  AdaptiveReport report;
  report.writer = Ranks::world().rank() == 0;
  AppearanceChoices no_appearance;
  no_appearance.skip = true;
  RandomSchedules guides(scene, stream(first.sampling.seed, kGuide), o.guide_schedules, o.schedule_items,
                         kKeptGuideTruthBytes);
  for (int r = 0;; ++r) {
    report.sampled = run_sample_rounds(scene, rounds, orbits);
    const auto round_package = work / fmt::format("round-{}.h5", r);
    const ReduceReport reduced = run_reduce_stage(scene, reduce, no_appearance, orbits, round_package);
    std::vector<PlayedSchedule> played;
    AdaptiveRound round;
    for (const auto& k : rounds) round.irfs += irfs_of(k);
    round.directed = r == 0 ? 0 : rounds.back().sampling.chains;
    judge_round(guides, reduced.package, o, r, report.writer, round, played);
    report.rounds.push_back(round);
    if ((round.fresh ? round.fresh_figures : round.guide).meets(o.target)) {
      report.met = true;
      report.stopped =
          round.fresh ? fmt::format("target met on the guide schedules and on {} fresh ones", round.fresh)
                      : std::string{"target met on the guide schedules"};
      break;
    }
    if (o.budget_minutes > 0 && clock.seconds() >= 60 * o.budget_minutes) {
      report.stopped = "time budget spent";
      break;
    }
    auto next = next_round(first, o, played, guides.directed(), r, round.irfs, work);
    if (!next) {
      report.stopped =
          directed_segments(played, o.target, 1).empty()
              ? "no guide segment left that plays out of the target and has had no directed chain"
              : "IRF budget spent";
      break;
    }
    rounds.push_back(std::move(*next));
  }
  return report;
}

}  // namespace phasecast::precompute
