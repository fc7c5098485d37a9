// The command-line flags of the sample, reduce and run subcommands, onto the
// pipeline's stage options (phasecast/precompute/pipeline/stages.h).

#include "stage_options.h"

#include <fmt/format.h>

namespace phasecast::precompute::tools {

void add_sample_options(CLI::App* cmd, SampleStageOptions& a) {
  auto& s = a.sampling;
  cmd->add_option("--chains", s.chains, "independent IRF chains (work units)")->capture_default_str();
  cmd->add_option("--irfs-per-chain", s.irfs_per_chain, "IRFs sampled by each chain")->capture_default_str();
  cmd->add_option("--seed", s.seed, "random seed: same seed, same orbits, bit for bit")
      ->capture_default_str();
  cmd->add_option("-j,--jobs", s.jobs, "chains simulated at once")->capture_default_str();
  cmd->add_option("--work-dir", a.work_dir, "checkpoint folder (default: <output>.work)");
  cmd->add_flag("--resume", s.resume, "continue from the checkpoints of an interrupted run");
  cmd->add_option("--stop-after-irfs", s.stop_after_irfs,
                  "stop after this many new IRFs (for testing resume)")
      ->group("");
}

void add_reduce_options(CLI::App* cmd, ReduceStageOptions& a) {
  auto& r = a.reduction;
  cmd->add_option("--eps-u", r.eps_u, "rank tolerance: r_u = largest r with sigma_r >= eps_u sigma_1")
      ->capture_default_str();
  cmd->add_option("--rank", r.rank, "fixed rank r_u instead of --eps-u (0: use --eps-u)")
      ->capture_default_str();
  cmd->add_option("--max-rank", r.max_rank, "singular values computed (length of the error curve)")
      ->capture_default_str();
  cmd->add_option("--power-iterations", r.power_iterations, "randomized SVD power iterations")
      ->capture_default_str();
  cmd->add_option("--svd-seed", r.seed, "seed of the randomized SVD")->capture_default_str();
  auto& p = a.package;
  cmd->add_option("--beta", p.beta, "velocity weight of eq. 9 (0: default of §2.3.2)")->capture_default_str();
  cmd->add_option("--blend-lambda", p.blend_lambda, "IRF blend decay rate, 1/s (eq. 12)")
      ->capture_default_str();
  cmd->add_option("--min-irf-frames", p.filter.min_frames, "drop IRFs with fewer state nodes")
      ->capture_default_str();
  cmd->add_option("--dead-end-fraction", p.filter.dead_end_fraction,
                  "drop IRFs ending farther than this x portrait radius from every IRF start (0: keep all)")
      ->capture_default_str();
}

void add_appearance_options(CLI::App* cmd, AppearanceChoices& a) {
  auto& s = a.stage;
  cmd->add_option("--clusters", a.clusters,
                  fmt::format("N_a: state nodes (k-means of q_u) whose transfer is computed (default: the "
                              "scene's [appearance] clusters, else {})",
                              kDefaultClusters));
  cmd->add_option(
      "--held-out", a.held_out,
      fmt::format("other state nodes whose true transfer measures the served appearance; half pick "
                  "the interpolant, half are reported (default: the scene's, else {}; 0: none)",
                  kDefaultHeldOut));
  cmd->add_option("--interpolant", a.interpolant,
                  "q_a over q_u: best (lowest held-out error), nrbf (§4.3), knn, affine-knn or "
                  "affine-knn-slope (its neighbours in the affine map's image) (docs/transfer.md)")
      ->capture_default_str();
  cmd->add_option("--transfer-weighting", a.weighting,
                  "weights of the cluster fields in M-bar and the SVD (§4.2): best (cluster-size where "
                  "its held-out gain is beyond its paired 95 % t interval, else equal; equal "
                  "without held-out nodes), equal (the paper's) or cluster-size (each cluster's share "
                  "of the state nodes)")
      ->capture_default_str();
  cmd->add_option("--cluster-seed", s.seed, "seed of the k-means++ clustering")->capture_default_str();
  cmd->add_option("--rays", a.rays,
                  fmt::format("transfer directions of the fixed sphere set (default: the scene's "
                              "[appearance] rays, else {})",
                              kDefaultRays));
  cmd->add_option("--bounces", s.transfer.bounces, "interreflection bounces (0: shadowed only)")
      ->capture_default_str();
  cmd->add_option(
      "--eps-a", a.eps_a,
      fmt::format("transfer rank tolerance: r_a = number of sigma_i >= eps_a sigma_1 (default: the "
                  "scene's [appearance] eps_a, else {})",
                  kDefaultEpsA));
  cmd->add_option("--rank-a", s.appearance.reduction.rank,
                  "fixed rank r_a instead of --eps-a (0: use --eps-a)")
      ->capture_default_str();
  cmd->add_option("--held-out-target", s.appearance.held_out_target,
                  "r_a = the least rank whose truncation alone at the picking half of the held-out nodes "
                  "(relative l2, the paper's relErr) is at most this, instead of --eps-a (0: off)")
      ->capture_default_str();
  cmd->add_option("--transfer-threads", s.transfer.threads, "threads of the ray caster (0: all cores)")
      ->capture_default_str();
  cmd->add_flag("--no-appearance", a.skip, "skip the appearance stage (no /appearance, r_a = 0)");
  cmd->add_option("--save-transfers", a.save_transfers,
                  "also write every true transfer the appearance stage computes (cluster representatives "
                  "and held-out nodes) to this HDF5 file, for analysis outside the tools (docs/transfer.md)");
}

}  // namespace phasecast::precompute::tools
