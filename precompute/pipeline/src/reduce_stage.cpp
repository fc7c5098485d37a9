// The reduce stage (§2.3, §5.2, §4): the randomized SVD of the orbit store,
// the phase portrait and IRF cache, then the appearance stage, into a package.

#include "phasecast/precompute/pipeline/stages.h"

#include "phasecast/core/process_memory.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "stopwatch.h"

#include <fmt/format.h>

#include <utility>

namespace phasecast::precompute {

namespace {

// The randomized SVD of A_u (§2.3.1), with its progress and timing.
DisplacementBasis reduce_with_progress(const OrbitDisplacementSource& A, const ReductionOptions& reduction) {
  const Stopwatch svd_time;
  core::ProgressBar bar("randomized SVD");
  auto options = reduction;
  options.progress = [&bar](int done, int total) { bar.update(done, total); };
  auto basis = reduce_displacements(A, options);
  bar.finish();
  if (Ranks::world().rank() == 0) {
    fmt::print(stderr, "randomized SVD of A_u ({} x {}): {:.1f} s, peak resident memory so far {:.0f} MiB\n",
               A.rows(), A.cols(), svd_time.seconds(), core::resident_memory().peak_mib);
  }
  return basis;
}

// The appearance stage (§4) on the package, its transfers split over the ranks.
AppearanceReport run_appearance(const Scene& scene, AppearanceStageOptions stage,
                                const OrbitDisplacementSource& A, const OrbitIndex& index,
                                const PackageBuild& built, core::ScenePackage& p) {
  const Stopwatch appearance_time;
  core::ProgressBar transfer_bar("appearance transfer");
  const auto& ranks = Ranks::world();
  stage.split.owns = [&ranks](long j) { return ranks.owns(static_cast<int>(j)); };
  stage.split.share = [&ranks](MatrixXfR& fields) { ranks.share_rows(fields); };
  AppearanceReport report;
  report.stage = run_appearance_stage(p, scene_point_embedding(scene), A,
                                      package_node_frames(index.irfs, built.filter.kept), stage,
                                      [&transfer_bar](const char* stage_name, long done, long total) {
                                        // each pass starts at 0: the transfers, then the nrbf's tuning
                                        if (done == 0) transfer_bar.restart(stage_name);
                                        transfer_bar.update(done, total);
                                      });
  transfer_bar.finish();
  report.seconds = appearance_time.seconds();
  report.peak_mib = core::resident_memory().peak_mib;
  if (ranks.rank() == 0) {
    fmt::print(stderr, "appearance stage: {:.1f} s, peak resident memory so far {:.0f} MiB\n", report.seconds,
               report.peak_mib);
  }
  core::validate_package(p, scene.name);
  return report;
}

// Per palette entry: sampled, kept and dropped IRFs with the reason.
std::vector<EntryIrfCounts> entry_irf_counts(const OrbitIndex& index, const OrbitFilterResult& filter) {
  std::vector<EntryIrfCounts> counts;
  for (const auto& name : index.palette_names) counts.push_back({name});
  const auto of = [&](int irf) -> EntryIrfCounts& {
    return counts.at(static_cast<size_t>(index.irfs.palette.at(static_cast<size_t>(irf))));
  };
  for (size_t i = 0; i < index.irfs.size(); ++i) ++of(static_cast<int>(i)).sampled;
  for (const int i : filter.kept) ++of(i).kept;
  for (const int i : filter.short_irfs) ++of(i).dropped_short;
  for (const int i : filter.dead_end_irfs) ++of(i).dropped_dead_end;
  return counts;
}

}  // namespace

ReduceReport run_reduce_stage(const Scene& scene, const ReduceStageOptions& a,
                              const AppearanceChoices& appearance, const std::filesystem::path& orbits,
                              const std::filesystem::path& package) {
  check_reduction_options(a.reduction);
  check_package_options(a.package);
  check_save_transfers(appearance, {orbits, package});
  const auto stage_options =
      appearance.skip ? AppearanceStageOptions{} : appearance_stage_options(scene, appearance);
  const auto rules = make_palette_rules(scene);
  const auto index = read_orbit_index(orbits);
  core::ProgressBar mean_bar("mean shape");
  const OrbitDisplacementSource A(orbits);
  mean_bar.update(1, 1);
  mean_bar.finish();
  const auto basis = reduce_with_progress(A, a.reduction);
  auto built = build_package(scene, rules, index, basis, a.package);
  ReduceReport report;
  report.writer = Ranks::world().rank() == 0;
  report.package_path = package;
  report.dropped_short = built.filter.dropped_short;
  report.dropped_dead_end = built.filter.dropped_dead_end;
  report.dropped = built.filter.messages;
  report.entries = entry_irf_counts(index, built.filter);
  if (report.writer)
    for (const auto& line : report.dropped) fmt::print(stderr, "dropped {}\n", line);
  if (!appearance.skip)
    report.appearance = run_appearance(scene, stage_options, A, index, built, built.package);
  if (report.writer) core::write_package(built.package, package);  // every rank computed it; one writes it
  report.package = std::move(built.package);
  return report;
}

}  // namespace phasecast::precompute
