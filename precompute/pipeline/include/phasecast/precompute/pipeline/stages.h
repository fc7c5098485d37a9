#pragma once
// The stages of phasecast-precompute run, in order: sample IRFs of a scene
// into an orbit store (§3.4), then reduce the store into a scene package
// (§2.3, §5.2) with its appearance (§4). Each stage runs on every MPI rank
// (docs/distributed.md), prints its progress to stderr as it goes, and
// returns a typed report; report_text.h says the report in words.

#include "phasecast/core/package.h"
#include "phasecast/precompute/appearance/appearance_stage.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/precompute/reduction/displacement_reduction.h"
#include "phasecast/precompute/sampling/irf_sampler.h"
#include "phasecast/precompute/simulation/self_collision.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::precompute {

struct SampleStageOptions {
  SamplingOptions sampling;
  std::filesystem::path work_dir;  // checkpoints; empty: <orbit store>.work
};

struct ReduceStageOptions {
  ReductionOptions reduction;
  PackageOptions package;
};

// What a user chose for the appearance stage, by name; the scene's
// [appearance] section and the built-in defaults fill in the rest
// (appearance_stage_options).
struct AppearanceChoices {
  AppearanceStageOptions stage;
  std::optional<int> clusters, held_out, rays;  // absent: the scene's, else the default below
  std::optional<double> eps_a;
  std::string interpolant = "best";      // best, nrbf, knn, affine-knn, affine-knn-slope
  std::string weighting = "best";        // best, equal, cluster-size
  bool skip = false;                     // no appearance stage: the package has no /appearance (r_a = 0)
  std::filesystem::path save_transfers;  // where every true transfer of the stage goes (empty: nowhere)
};

// The built-in appearance defaults, where neither the command line nor the scene says.
inline constexpr int kDefaultClusters = 16;
inline constexpr int kDefaultHeldOut = 40;
inline constexpr int kDefaultRays = 1024;
inline constexpr double kDefaultEpsA = 1e-3;

// The stage's options for this scene: the choices, else the scene's
// [appearance] defaults, else the built-in ones; the scene's albedo per
// point. Throws std::invalid_argument naming the flag of a bad value.
AppearanceStageOptions appearance_stage_options(const Scene& scene, const AppearanceChoices& choices);

// save_transfers is checked before any work: a file (not a folder) in an
// existing folder this user can write, none of `inputs_and_outputs` (the
// orbit store, the package), and the stage it saves from must run. Throws
// std::invalid_argument.
void check_save_transfers(const AppearanceChoices& choices,
                          const std::vector<std::filesystem::path>& inputs_and_outputs);

struct SampleReport {
  bool writer = false;  // this rank wrote the store (rank 0): the one that reports
  std::filesystem::path orbits;
  long irfs = 0, frames = 0;              // in the merged store
  double merge_seconds = 0;               // merging the chain stores
  std::optional<ContactSummary> contact;  // every sampled frame (scenes with self-collision)
  double close_distance = 0;              // what counts as close in `contact`
};

// Samples IRFs of the scene and writes the merged orbit store to `orbits`.
SampleReport run_sample_stage(const Scene& scene, SampleStageOptions options,
                              const std::filesystem::path& orbits);

// Several sampling runs, each in its own work folder (an adaptive run's
// rounds): the last is sampled (or resumed), every earlier one must be
// complete, and all are merged in order into `orbits`.
SampleReport run_sample_rounds(const Scene& scene, const std::vector<SampleStageOptions>& rounds,
                               const std::filesystem::path& orbits);

struct AppearanceReport {
  AppearanceStageReport stage;
  double seconds = 0;
  double peak_mib = 0;  // resident memory so far
};

// One palette entry's IRFs through the filter (§3.5: short ones and dead ends are dropped).
struct EntryIrfCounts {
  std::string entry;
  int sampled = 0, kept = 0, dropped_short = 0, dropped_dead_end = 0;
};

struct ReduceReport {
  bool writer = false;  // this rank wrote the package (rank 0): the one that reports
  std::filesystem::path package_path;
  core::ScenePackage package;
  int dropped_short = 0, dropped_dead_end = 0;
  std::vector<std::string> dropped;     // one line per IRF the filter dropped, naming its entry and why
  std::vector<EntryIrfCounts> entries;  // per palette entry, in palette order
  std::optional<AppearanceReport> appearance;  // absent: skipped
};

// Reduces the orbit store, runs the appearance stage on it (unless skipped)
// and writes the package.
ReduceReport run_reduce_stage(const Scene& scene, const ReduceStageOptions& options,
                              const AppearanceChoices& appearance, const std::filesystem::path& orbits,
                              const std::filesystem::path& package);

}  // namespace phasecast::precompute
