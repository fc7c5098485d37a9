// The sampling stage (§3.4): chains of IRFs on every rank, merged by rank 0
// into one orbit store, with the self-contact of every sampled frame.

#include "phasecast/precompute/pipeline/stages.h"

#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/pipeline/contact_report.h"
#include "stopwatch.h"

#include <fmt/format.h>

#include <memory>

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
ContactSummary sampled_contact(const Scene& scene, const SamplingOptions& o) {
  const auto& ranks = Ranks::world();
  std::vector<std::filesystem::path> mine;
  for (int k = ranks.rank(); k < o.chains; k += ranks.size())
    mine.push_back(chain_store_path(o.work_dir, k));
  ContactSummary c = store_contact(scene, mine);
  std::vector<long long> counts{c.frames, c.frames_intersecting, c.frames_close};
  ranks.sum(counts);
  c.frames = static_cast<int>(counts[0]);
  c.frames_intersecting = static_cast<int>(counts[1]);
  c.frames_close = static_cast<int>(counts[2]);
  c.worst_intersecting = static_cast<int>(ranks.max(c.worst_intersecting));
  c.closest = ranks.min(c.closest);
  return c;
}

}  // namespace

SampleReport run_sample_stage(const Scene& scene, SampleStageOptions a, const std::filesystem::path& orbits) {
  const auto& ranks = Ranks::world();
  a.sampling.ranks = ranks.size();
  a.sampling.rank = ranks.rank();
  check_sampling_options(a.sampling);
  a.sampling.work_dir = a.work_dir.empty() ? std::filesystem::path(orbits.string() + ".work") : a.work_dir;
  const auto rules = make_palette_rules(scene);
  if (ranks.rank() == 0) {
    fmt::print(stderr, "{}: {} vertices, {} palette entries, {} chains x {} IRFs, seed {}{}{}\n", scene.name,
               scene.model.vertices(), scene.palette.size(), a.sampling.chains, a.sampling.irfs_per_chain,
               a.sampling.seed, ranks.distributed() ? fmt::format(", {} MPI ranks", ranks.size()) : "",
               a.sampling.resume ? " (resuming)" : "");
  }
  auto display = std::make_shared<SamplingDisplay>();
  a.sampling.progress = [display](const SamplingProgress& p) { (*display)(p); };
  a.sampling.notice = [](const std::string& line) { fmt::print(stderr, "\n{}\n", line); };
  a.sampling.chain_sampled = [&ranks](const ChainSampled& c) {
    fmt::print(
        stderr,
        "\n{}chain {}: {} IRFs, {} state nodes in {:.1f} s (settling {:.1f} s, then {:.0f} ms per node)\n",
        ranks.distributed() ? fmt::format("rank {}: ", ranks.rank()) : "", c.chain, c.irfs, c.frames,
        c.seconds, c.settle_seconds, 1e3 * (c.seconds - c.settle_seconds) / static_cast<double>(c.frames));
  };
  MergedStore merged;
  SampleReport report;
  report.writer = ranks.rank() == 0;
  report.orbits = orbits;
  try {
    // Each rank's chains stream into their stores in the work folder; rank 0
    // then merges them in chain order into the orbit store, one IRF at a
    // time, as one process would (docs/distributed.md).
    sample_own_chains(scene, rules, a.sampling);
    ranks.barrier();
    const Stopwatch merge;
    if (ranks.rank() == 0) merged = write_chain_stores(scene, a.sampling, orbits);
    report.merge_seconds = merge.seconds();
  } catch (...) {
    display->finish();
    throw;
  }
  display->finish();
  report.irfs = merged.irfs;
  report.frames = merged.frames;
  if (scene.model.self_collision) {
    report.contact = sampled_contact(scene, a.sampling);
    report.close_distance = close_distance(scene);
  }
  ranks.barrier();  // the store is complete before any rank reads it
  return report;
}

}  // namespace phasecast::precompute
