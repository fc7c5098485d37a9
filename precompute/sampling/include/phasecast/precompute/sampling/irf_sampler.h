#pragma once
// Random IRF sampling (§3.4): independent chains of palette entries obeying
// the palette rules, each IRF integrated for a random T in (t_min, t_max).
// Each chain checkpoints after every IRF into the work folder (its orbit store
// chain-<k>.h5 and the exact simulator state chain-<k>.state.h5), so that a
// resumed run continues bit-identically without losing or duplicating orbits.
// A chain holds only the IRF it is recording: each IRF is appended to the
// chain's store (OrbitStoreAppender) and dropped, so a chain's memory and the
// bytes it writes per IRF do not grow with its length.

#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/simulation/scene.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::precompute {

// A run stopped on purpose (--stop-after-irfs) or a checkpoint that cannot be resumed.
class SamplingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SamplingProgress {
  int irfs_done = 0;
  int irfs_total = 0;
  long long nodes = 0;  // state nodes (frames) recorded so far, all chains
};

// A chain that has sampled the IRFs it lacked: the unit of work of a run
// spread over many ranks, timed (docs/distributed.md).
struct ChainSampled {
  int chain = 0;
  int irfs = 0;               // sampled by this run (a resumed chain's earlier IRFs not counted)
  long long frames = 0;       // state nodes of those IRFs
  double seconds = 0;         // wall time, settling included
  double settle_seconds = 0;  // of it, relaxing to the settled rest the chain starts from
};

struct SamplingOptions {
  int chains = 4;           // independent work units
  int irfs_per_chain = 16;  // IRFs sampled by each chain
  std::uint64_t seed = 1;   // same seed => bit-identical orbits
  int jobs = 2;             // chains simulated at once (threads)
  std::filesystem::path work_dir;
  bool resume = false;      // continue from the checkpoints in work_dir
  int stop_after_irfs = 0;  // > 0: stop (SamplingError) once this many new IRFs are checkpointed (tests)
  // One line when --resume finds a chain store it cannot continue (a crash tore
  // the file) and samples the chain again from its start.
  std::function<void(const std::string&)> notice;
  // Chain k runs in the process of rank k mod ranks (an MPI run, docs/distributed.md).
  int ranks = 1;
  int rank = 0;
  std::function<void(const SamplingProgress&)> progress;
  std::function<void(const ChainSampled&)> chain_sampled;  // called from the chain's thread
  // Directed chains (adaptive sampling, docs/sampling.md): chain k plays
  // lead_ins[k] from rest, simulating but not recording its items but the
  // last kRecordedLeadIns, which are the chain's first IRFs; it then draws the
  // rest of its IRFs as any chain does. Empty, or shorter than `chains`: the
  // chains past it start at rest.
  std::vector<std::vector<ScheduleItem>> lead_ins;
};

// A directed chain records its lead-in's last two items: the segment and the
// one before it, so the segment's IRF continues a stored IRF and its start has
// the velocity the impulse finds (a moving start would otherwise be stored
// still, as every start that continues nothing is).
inline constexpr size_t kRecordedLeadIns = 2;

// The chain-th chain's decision for its `irf`-th IRF given its history (the
// entries since it last left rest, oldest first) and the support coordinate
// `at` where the IRF starts: the entry and its length in frames. Entries the
// support's range blocks are never drawn, and T is clipped to the remaining
// range (§3.5). A pure function of its arguments, so resumes replay it exactly.
struct IrfDraw {
  int entry = 0;
  int frames = 1;
  bool from_rest = false;  // no entry may follow: the chain restarts from the settled rest state
};
IrfDraw draw_irf(const PaletteRules& rules, std::uint64_t seed, int chain, int irf,
                 const std::vector<int>& history, double at = 0);

// The chain's `irf`-th IRF: its lead-in's last kRecordedLeadIns items first
// (T clipped to the support's range like a drawn one), then draw_irf.
IrfDraw next_irf(const PaletteRules& rules, const SamplingOptions& options, double frame_dt, int chain,
                 int irf, const std::vector<int>& history, double at);

// Chain k's orbit store in the work folder (chain-<k>.h5).
std::filesystem::path chain_store_path(const std::filesystem::path& work_dir, int chain);

// Throws SamplingError naming the bad option (chains, IRFs per chain, jobs >= 1).
void check_sampling_options(const SamplingOptions& options);

// Runs (or resumes) every chain and returns their orbits concatenated in chain
// order (options.ranks must be 1), read back from the chain stores: the
// merged store is whole in memory (write_chain_stores streams it instead).
OrbitStore sample_irfs(const Scene& scene, const PaletteRules& rules, const SamplingOptions& options);

// Runs (or resumes) this rank's chains, leaving each complete in its store in
// options.work_dir. A failure names the chain.
void sample_own_chains(const Scene& scene, const PaletteRules& rules, const SamplingOptions& options);

// Every chain's store from options.work_dir, concatenated in chain order: what
// sample_irfs returns, once all ranks have run their chains. Throws
// SamplingError naming a missing or incomplete chain store.
OrbitStore read_chain_stores(const Scene& scene, const SamplingOptions& options);

struct MergedStore {
  int irfs = 0;
  long long frames = 0;
};

// The same concatenation written to `path` (atomically, as write_orbit_store)
// one IRF at a time, so that merging holds one IRF rather than every chain.
// Throws SamplingError as read_chain_stores before writing anything.
MergedStore write_chain_stores(const Scene& scene, const SamplingOptions& options,
                               const std::filesystem::path& path);

// The chains of several runs (an adaptive run's rounds, each with its own
// work folder), concatenated in the order given.
MergedStore write_chain_stores(const Scene& scene, const std::vector<SamplingOptions>& runs,
                               const std::filesystem::path& path);

}  // namespace phasecast::precompute
