// The sampling stage (§3.4): chains of IRFs on every rank, merged by rank 0
// into one orbit store, with the self-contact of every sampled frame.

#include "phasecast/precompute/pipeline/stages.h"

#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/pipeline/contact_report.h"
#include "stopwatch.h"

#include <fmt/format.h>

#include <memory>
#include <stdexcept>
#include <utility>

namespace phasecast::precompute {
namespace {

// Sampling progress: IRFs done/total, state nodes and ETA (resumed IRFs do
// not count towards the rate).
class SamplingDisplay {
 public:
  void operator()(const SamplingProgress& p) {
    bar_.update(p.irfs_done, p.irfs_total, fmt::format("{} state nodes", p.nodes));
  }
  void finish() { bar_.finish(); }

 private:
  core::ProgressBar bar_{"sample IRFs"};
};

// The self-contact of every sampled frame: each rank reads its own chains'
// stores (the merged store holds the same frames), then the counts are
// summed and the extremes combined over the ranks: exact, for any N.
ContactSummary sampled_contact(const Scene& scene, const std::vector<SamplingOptions>& runs) {
  const auto& ranks = Ranks::world();
  std::vector<std::filesystem::path> mine;
  for (const auto& o : runs)
    for (int k = ranks.rank(); k < o.chains; k += ranks.size())
      mine.push_back(chain_store_path(o.work_dir, k));
  ContactSummary c = store_contact(scene, mine);
  std::vector<long long> counts{c.frames, c.frames_intersecting, c.frames_close, c.frames_in_contact};
  ranks.sum(counts);
  c.frames = static_cast<int>(counts[0]);
  c.frames_intersecting = static_cast<int>(counts[1]);
  c.frames_close = static_cast<int>(counts[2]);
  c.frames_in_contact = static_cast<int>(counts[3]);
  c.worst_intersecting = static_cast<int>(ranks.max(c.worst_intersecting));
  c.closest = ranks.min(c.closest);
  c.closest_to_triangle = ranks.min(c.closest_to_triangle);
  return c;
}

// The run's options on this rank, checked, its work folder defaulting to <orbits>.work.
SamplingOptions on_this_rank(const SampleStageOptions& a, const std::filesystem::path& orbits) {
  const auto& ranks = Ranks::world();
  SamplingOptions o = a.sampling;
  o.ranks = ranks.size();
  o.rank = ranks.rank();
  check_sampling_options(o);
  o.work_dir = a.work_dir.empty() ? std::filesystem::path(orbits.string() + ".work") : a.work_dir;
  return o;
}

// Samples (or resumes) this rank's chains of `o`, with a progress bar and a line per chain.
void sample_with_progress(const Scene& scene, SamplingOptions o) {
  const auto& ranks = Ranks::world();
  const auto rules = make_palette_rules(scene);  // a bad rule fails before anything is printed
  if (ranks.rank() == 0) {
    fmt::print(stderr, "{}: {} vertices, {} palette entries, {} chains x {} IRFs{}, seed {}{}{}\n",
               scene.name, scene.model.vertices(), scene.palette.size(), o.chains, o.irfs_per_chain,
               o.lead_ins.empty() ? "" : " (directed)", o.seed,
               ranks.distributed() ? fmt::format(", {} MPI ranks", ranks.size()) : "",
               o.resume ? " (resuming)" : "");
  }
  auto display = std::make_shared<SamplingDisplay>();
  o.progress = [display](const SamplingProgress& p) { (*display)(p); };
  o.notice = [](const std::string& line) { fmt::print(stderr, "\n{}\n", line); };
  o.chain_sampled = [&ranks](const ChainSampled& c) {
    fmt::print(
        stderr,
        "\n{}chain {}: {} IRFs, {} state nodes in {:.1f} s (settling {:.1f} s, then {:.0f} ms per node)\n",
        ranks.distributed() ? fmt::format("rank {}: ", ranks.rank()) : "", c.chain, c.irfs, c.frames,
        c.seconds, c.settle_seconds, 1e3 * (c.seconds - c.settle_seconds) / static_cast<double>(c.frames));
  };
  try {
    // Each rank's chains stream into their stores in the work folder (docs/distributed.md).
    sample_own_chains(scene, rules, o);
  } catch (...) {
    display->finish();
    throw;
  }
  display->finish();
}

}  // namespace

SampleReport run_sample_rounds(const Scene& scene, const std::vector<SampleStageOptions>& rounds,
                               const std::filesystem::path& orbits) {
  if (rounds.empty()) throw std::invalid_argument("run_sample_rounds: no sampling round");
  const auto& ranks = Ranks::world();
  std::vector<SamplingOptions> runs;
  for (const auto& r : rounds) runs.push_back(on_this_rank(r, orbits));
  sample_with_progress(scene, runs.back());
  ranks.barrier();
  SampleReport report;
  report.writer = ranks.rank() == 0;
  report.orbits = orbits;
  const Stopwatch merge;
  // Rank 0 merges every round's chains, in order, into the orbit store, one
  // IRF at a time, as one process would.
  if (report.writer) {
    const MergedStore merged = write_chain_stores(scene, runs, orbits);
    report.irfs = merged.irfs;
    report.frames = merged.frames;
  }
  report.merge_seconds = merge.seconds();
  if (scene.model.self_collision) {
    report.contact = sampled_contact(scene, runs);
    report.close_distance = close_distance(scene);
  }
  ranks.barrier();  // the store is complete before any rank reads it
  return report;
}

SampleReport run_sample_stage(const Scene& scene, SampleStageOptions options,
                              const std::filesystem::path& orbits) {
  return run_sample_rounds(scene, {std::move(options)}, orbits);
}

}  // namespace phasecast::precompute
