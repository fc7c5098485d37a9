#include "pipeline.h"

#include "contact_report.h"

#include "phasecast/core/package.h"
#include "phasecast/core/package_summary.h"
#include "phasecast/core/process_memory.h"
#include "phasecast/core/progress.h"
#include "phasecast/precompute/distributed/ranks.h"
#include "phasecast/precompute/reduction/displacement_reduction.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <chrono>
#include <cmath>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>  // access(): is the folder of --save-transfers writable

namespace phasecast::precompute::tools {
namespace {

class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

constexpr int kDefaultClusters = 16;
constexpr int kDefaultHeldOut = 40;
constexpr int kDefaultRays = 1024;
constexpr double kDefaultEpsA = 1e-3;

// Sampling progress: IRFs done/total, state nodes and ETA (resumed IRFs do
// not count towards the rate).
class SamplingDisplay {
 public:
  void operator()(const precompute::SamplingProgress& p) {
    bar_.update(p.irfs_done, p.irfs_total, fmt::format("{} state nodes", p.nodes));
  }
  void finish() { bar_.finish(); }

 private:
  core::ProgressBar bar_{"sample IRFs"};
};

// The self-contact of every sampled frame: each rank reads its own chains'
// stores (the merged store holds the same frames), then the counts are
// summed and the extremes combined over the ranks: exact, for any N.
ContactSummary sampled_contact(const precompute::Scene& scene, const precompute::SamplingOptions& o) {
  const auto& ranks = Ranks::world();
  std::vector<std::filesystem::path> mine;
  for (int k = ranks.rank(); k < o.chains; k += ranks.size())
    mine.push_back(precompute::chain_store_path(o.work_dir, k));
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

// "deformable points 74 % / 88 % (0.0873), props 26 % / 12 % (0.0552); SH band 0 ...": each
// part's share of the variation and of the residual, and its relative error.
std::string residual_parts(const precompute::ResidualByPart& r) {
  const auto part = [](const char* name, const precompute::PartOfResidual& x) {
    return fmt::format("{} {:.0f} % / {:.0f} % ({:.4f})", name, 100 * x.of_data, 100 * x.of_residual,
                       x.relative);
  };
  return fmt::format("{}, {}; SH band {}, {}, {}, {}", part("deformable points", r.points[0]),
                     part("props", r.points[1]), part("0", r.bands[0]), part("1", r.bands[1]),
                     part("2", r.bands[2]), part("3", r.bands[3]));
}

void print_residual_parts(const precompute::AppearanceStageReport& report) {
  fmt::print(
      "appearance: where the truncation error lives (share of the variation about M-bar / of what U_a "
      "leaves of it (relative error)): clusters {:.4f}: {}\n",
      report.clusters_residual.relative, residual_parts(report.clusters_residual));
  if (const auto& h = report.held_out_residual)
    fmt::print("  held-out nodes {:.4f}: {}\n", h->relative, residual_parts(*h));
}

// The served basis against one of the picking half's own fields, with the
// paired verdict (a single draw's figures alone would call any difference).
void print_basis_comparison(const precompute::BasisComparison& b, Eigen::Index clusters, Eigen::Index r) {
  const auto& g = b.drawn_gain;
  const std::string verdict =
      g.beyond_noise()    ? "the drawn basis is the better one: other states would give a better basis"
      : -g.gain > g.noise ? "the clusters' basis is the better one: as many random states miss more"
                          : "within noise of each other";
  fmt::print(
      "appearance: truncation alone at the reported half, relative to the nodes' own variation (Frobenius / "
      "l2): the {} clusters' basis {:.4f} / {:.4f}; a rank-{} basis of the picking half's own {} fields "
      "(random states) {:.4f} / {:.4f}, which leaves {:.1f} % {} squared error, noise {} (95 % t "
      "interval of the paired differences): {}{}\n",
      clusters, b.served.of_variation, b.served.l2_of_variation, r, b.drawn_fields, b.drawn.of_variation,
      b.drawn.l2_of_variation, 100 * std::abs(g.gain), g.gain >= 0 ? "less" : "more",
      std::isfinite(g.noise) ? fmt::format("{:.1f} %", 100 * g.noise) : "unbounded", verdict,
      b.drawn_fields < clusters
          ? fmt::format(" (from fewer fields than the {} clusters: --held-out {} compares "
                        "like with like)",
                        clusters, 2 * clusters)
          : std::string());
}

// How --held-out-target set r_a, at the picking half (the reported half never saw it).
void print_rank_choice(const precompute::HeldOutRankChoice& c) {
  if (c.reached) {
    fmt::print(
        "appearance: r_a = {}, the least rank whose truncation alone at the picking half's {} nodes "
        "(relative l2, equal weights) is at most {:.4f}: it reads {:.4f}\n",
        c.rank, c.picking_nodes, c.target, c.truncation);
  } else {
    fmt::print(
        "appearance: no rank of the clusters brings the truncation at the picking half's {} nodes to {:.4f} "
        "(all {} directions leave {:.4f}): r_a = {}, all of them (more clusters lower what they leave)\n",
        c.picking_nodes, c.target, c.rank, c.truncation, c.rank);
  }
}

void print_appearance_report(const core::ScenePackage& p, const precompute::AppearanceStageReport& report) {
  const auto& a = *p.appearance;
  const auto r = p.rank_a();
  const bool has_next = r > 0 && r < a.singular_values.size() && a.singular_values[0] > 0;
  fmt::print(
      "appearance: N_a = {} clusters, {} scene points, r_a = {} (of the paper's A_a: truncation error {:.4f} "
      "on the clusters, sigma_{{r+1}}/sigma_1 {}, the paper's relErr); U_a and M-bar from the fields "
      "weighted "
      "{}\n",
      a.clusters(), p.mesh.points(), r, r > 0 ? a.rel_error[r - 1] : 0.0f,
      has_next ? fmt::format("{:.4f}", a.singular_values[r] / a.singular_values[0]) : std::string("n/a"),
      a.transfer_weighting);
  if (const auto& c = report.rank_choice) print_rank_choice(*c);
  for (const auto& c : report.candidates) {
    const auto& f = c.interpolant;
    const std::string params =
        f.kind == precompute::InterpolantKind::nrbf
            ? fmt::format("width scale {}, lambda {:g}", f.width_scale, f.nrbf.regularization)
        : precompute::has_affine_map(f.kind)
            ? fmt::format("k = {}, ridge {:g}", f.neighbours, f.nrbf.regularization)
            : fmt::format("k = {}", f.neighbours);
    fmt::print("  {} weights, interpolant {} ({}): leave-one-out {:.4f}",
               precompute::weighting_name(c.weighting), precompute::interpolant_name(f.kind), params,
               f.leave_one_out);
    if (!a.held_out_nodes.empty())
      fmt::print(
          ", held-out error of |M| {:.4f} (picking half) / {:.4f} (reported half), of the nodes' own "
          "variation {:.4f} / {:.4f}",
          c.selection.of_transfer, c.test.of_transfer, c.selection.of_variation, c.test.of_variation);
    fmt::print("{}\n", &c == &report.candidates.front() ? "  <- kept" : "");
  }
  if (const auto& g = report.weighting_gain) {
    fmt::print(
        "appearance: cluster sizes leave {:.1f} % {} squared error than equal weights at the picking "
        "half's nodes, noise {} (95 % t interval of the paired differences): {}\n",
        100 * std::abs(g->gain), g->gain >= 0 ? "less" : "more",
        std::isfinite(g->noise) ? fmt::format("{:.1f} %", 100 * g->noise) : "unbounded",
        g->beyond_noise() ? "beyond it, cluster sizes kept"
        : g->gain > 0     ? "within it, the paper's equal weights kept"
                          : "the paper's equal weights kept");
  }
  if (a.held_out_error.size() >= 8) {
    fmt::print(
        "appearance: held-out error over {} nodes {:.4f} = truncation {:.4f} + interpolation {:.4f} (in "
        "quadrature, relative to |M - M-bar|); {:.4f} of |M|; relative l2 norm (the paper's relErr) {:.4f}, "
        "truncation alone {:.4f}, the clusters' own truncation over as many of them (all, if fewer) {:.4f}, "
        "the least any rank-{} model about M-bar reaches at those nodes {:.4f}\n",
        a.held_out_nodes.size(), a.held_out_error[0], a.held_out_error[1], a.held_out_error[2],
        a.held_out_error[3], a.held_out_error[4], a.held_out_error[5], a.held_out_error[6], a.U_a.cols(),
        a.held_out_error[7]);
  }
  if (a.held_out_error.size() == 11) {
    fmt::print(
        "appearance: relative to the nodes' own variation |M - their mean| (no model moves it): {:.4f}, "
        "relative l2 {:.4f}; the least any rank-{} model reaches there, whatever its mean, {:.4f}\n",
        a.held_out_error[8], a.held_out_error[9], a.U_a.cols(), a.held_out_error[10]);
  }
  if (a.held_out_spread.size() >= 4) {
    fmt::print(
        "appearance: over resampled held-out nodes (10th-90th percentile) relative l2 {:.4f}-{:.4f}, "
        "truncation alone {:.4f}-{:.4f}{}\n",
        a.held_out_spread[0], a.held_out_spread[1], a.held_out_spread[2], a.held_out_spread[3],
        a.held_out_spread.size() == 6 ? fmt::format("; relative l2 of their own variation {:.4f}-{:.4f}",
                                                    a.held_out_spread[4], a.held_out_spread[5])
                                      : std::string());
  }
  if (const auto& curve = a.held_out_truncation_curve; curve.size() > 0) {
    fmt::print("appearance: held-out truncation by rank (Fig. 12 out of sample, relative l2): {}\n",
               core::held_out_curve_text(std::vector<double>(curve.data(), curve.data() + curve.size()), r,
                                         a.paper_rank,
                                         a.held_out_error.size() >= 7 ? a.held_out_error[6] : std::nan("")));
  }
  if (const auto& b = report.basis_comparison) print_basis_comparison(*b, a.clusters(), r);
  if (r > 0) print_residual_parts(report);
}

// The value of `flag` named `value`; a one-line error listing the names otherwise.
template <class Choice>
Choice named_choice(const char* flag, const std::string& value,
                    std::initializer_list<std::pair<const char*, Choice>> names) {
  std::vector<std::string> listed;
  for (const auto& [name, choice] : names) {
    if (value == name) return choice;
    listed.emplace_back(name);
  }
  const std::string last = listed.back();
  listed.pop_back();
  throw std::invalid_argument(
      fmt::format("{} '{}': expected {} or {}", flag, value, fmt::join(listed, ", "), last));
}

}  // namespace

void add_sample_options(CLI::App* cmd, SampleArgs& a) {
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

void add_reduce_options(CLI::App* cmd, ReduceArgs& a) {
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

void add_appearance_options(CLI::App* cmd, AppearanceArgs& a) {
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

void check_save_transfers(const AppearanceArgs& a,
                          const std::vector<std::filesystem::path>& inputs_and_outputs) {
  if (a.save_transfers.empty()) return;
  if (a.skip)
    throw std::invalid_argument(
        "appearance: --save-transfers saves the appearance stage's transfers: drop --no-appearance");
  const std::filesystem::path file = std::filesystem::absolute(a.save_transfers);
  std::error_code ec;
  const auto expected = [&a](const std::string& what) {
    return std::invalid_argument(
        fmt::format("appearance: --save-transfers '{}': expected {}", a.save_transfers, what));
  };
  if (!std::filesystem::is_directory(file.parent_path(), ec))
    throw expected(fmt::format("a file in an existing folder ({} is not one)", file.parent_path().string()));
  if (std::filesystem::is_directory(file, ec)) throw expected("a file, not a folder");
  if (::access(file.parent_path().c_str(), W_OK) != 0)
    throw expected(
        fmt::format("a file in a folder this user can write ({} is not)", file.parent_path().string()));
  for (const auto& other : inputs_and_outputs) {
    // The transfers file is renamed over its path: it must not replace the orbit store or the package.
    if (std::filesystem::weakly_canonical(file, ec) == std::filesystem::weakly_canonical(other, ec))
      throw expected(fmt::format("a file other than the orbit store and the package ({})", other.string()));
  }
}

precompute::AppearanceStageOptions appearance_stage_options(const precompute::Scene& scene,
                                                            const AppearanceArgs& a) {
  auto s = a.stage;
  const auto& d = scene.appearance;
  s.clusters = a.clusters.value_or(d.clusters > 0 ? d.clusters : kDefaultClusters);
  s.held_out = a.held_out.value_or(d.held_out > 0 ? d.held_out : kDefaultHeldOut);
  s.transfer.rays = a.rays.value_or(d.rays > 0 ? d.rays : kDefaultRays);
  s.appearance.reduction.eps_a = a.eps_a.value_or(d.eps_a > 0 ? d.eps_a : kDefaultEpsA);
  s.appearance.interpolant = named_choice<precompute::InterpolantChoice>(
      "--interpolant", a.interpolant,
      {{"best", precompute::InterpolantChoice::best},
       {"nrbf", precompute::InterpolantChoice::nrbf},
       {"knn", precompute::InterpolantChoice::knn},
       {"affine-knn", precompute::InterpolantChoice::affine_knn},
       {"affine-knn-slope", precompute::InterpolantChoice::affine_knn_slope}});
  s.appearance.weighting = named_choice<precompute::WeightingChoice>(
      "--transfer-weighting", a.weighting,
      {{"best", precompute::WeightingChoice::best},
       {"equal", precompute::WeightingChoice::equal},
       {"cluster-size", precompute::WeightingChoice::cluster_size}});
  s.paper_rank = d.paper_rank_a;
  s.transfer.point_albedo = precompute::scene_point_albedo(scene);
  precompute::check_appearance_stage_options(s);
  if (!a.save_transfers.empty()) {
    s.keep_transfers = [path = a.save_transfers](const precompute::StageTransfers& t) {
      if (Ranks::world().rank() != 0) return;  // every rank holds them all; one writes
      try {
        precompute::write_stage_transfers(t, path);
        fmt::print(stderr, "appearance: wrote {} ({} transfers of {} scene points)\n", path, t.nodes.size(),
                   t.rest_positions.rows());
      } catch (const std::exception& e) {
        // A full disk must not cost the package the transfers were computed for.
        fmt::print(stderr, "appearance: --save-transfers: {}; the package is made without it\n", e.what());
      }
    };
  }
  return s;
}

void run_sample_stage(const precompute::Scene& scene, SampleArgs a, const std::filesystem::path& orbits) {
  const auto& ranks = Ranks::world();
  a.sampling.ranks = ranks.size();
  a.sampling.rank = ranks.rank();
  precompute::check_sampling_options(a.sampling);
  a.sampling.work_dir = a.work_dir.empty() ? std::filesystem::path(orbits.string() + ".work")
                                           : std::filesystem::path(a.work_dir);
  const auto rules = precompute::make_palette_rules(scene);
  if (ranks.rank() == 0) {
    fmt::print(stderr, "{}: {} vertices, {} palette entries, {} chains x {} IRFs, seed {}{}{}\n", scene.name,
               scene.model.vertices(), scene.palette.size(), a.sampling.chains, a.sampling.irfs_per_chain,
               a.sampling.seed, ranks.distributed() ? fmt::format(", {} MPI ranks", ranks.size()) : "",
               a.sampling.resume ? " (resuming)" : "");
  }
  auto display = std::make_shared<SamplingDisplay>();
  a.sampling.progress = [display](const precompute::SamplingProgress& p) { (*display)(p); };
  a.sampling.notice = [](const std::string& line) { fmt::print(stderr, "\n{}\n", line); };
  a.sampling.chain_sampled = [&ranks](const precompute::ChainSampled& c) {
    fmt::print(
        stderr,
        "\n{}chain {}: {} IRFs, {} state nodes in {:.1f} s (settling {:.1f} s, then {:.0f} ms per node)\n",
        ranks.distributed() ? fmt::format("rank {}: ", ranks.rank()) : "", c.chain, c.irfs, c.frames,
        c.seconds, c.settle_seconds, 1e3 * (c.seconds - c.settle_seconds) / static_cast<double>(c.frames));
  };
  precompute::MergedStore merged;
  double merge_seconds = 0;
  try {
    // Each rank's chains stream into their stores in the work folder; rank 0
    // then merges them in chain order into the orbit store, one IRF at a
    // time, as one process would (docs/distributed.md).
    precompute::sample_own_chains(scene, rules, a.sampling);
    ranks.barrier();
    const Stopwatch merge;
    if (ranks.rank() == 0) merged = precompute::write_chain_stores(scene, a.sampling, orbits);
    merge_seconds = merge.seconds();
  } catch (...) {
    display->finish();
    throw;
  }
  display->finish();
  if (ranks.rank() == 0) {
    fmt::print("wrote {} ({} IRFs, {} state nodes; chain stores merged in {:.1f} s)\n", orbits.string(),
               merged.irfs, merged.frames, merge_seconds);
  }
  if (scene.model.self_collision) {
    const ContactSummary c = sampled_contact(scene, a.sampling);
    if (ranks.rank() == 0) fmt::print("{}\n", contact_line(c, close_distance(scene)));
  }
  ranks.barrier();  // the store is complete before any rank reads it
}

void run_reduce_stage(const precompute::Scene& scene, const ReduceArgs& a, const AppearanceArgs& appearance,
                      const std::filesystem::path& orbits, const std::filesystem::path& package) {
  precompute::check_reduction_options(a.reduction);
  precompute::check_package_options(a.package);
  check_save_transfers(appearance, {orbits, package});
  const auto stage_options =
      appearance.skip ? precompute::AppearanceStageOptions{} : appearance_stage_options(scene, appearance);
  const auto rules = precompute::make_palette_rules(scene);
  const auto index = precompute::read_orbit_index(orbits);
  const Stopwatch svd_time;
  core::ProgressBar mean_bar("mean shape");
  const precompute::OrbitDisplacementSource A(orbits);
  mean_bar.update(1, 1);
  mean_bar.finish();
  core::ProgressBar bar("randomized SVD");
  auto options = a.reduction;
  options.progress = [&bar](int done, int total) { bar.update(done, total); };
  const auto basis = precompute::reduce_displacements(A, options);
  bar.finish();
  if (Ranks::world().rank() == 0) {
    fmt::print(stderr, "randomized SVD of A_u ({} x {}): {:.1f} s, peak resident memory so far {:.0f} MiB\n",
               A.rows(), A.cols(), svd_time.seconds(), core::resident_memory().peak_mib);
  }
  auto built = precompute::build_package(scene, rules, index, basis, a.package);
  if (Ranks::world().rank() == 0)
    for (const auto& line : built.filter.messages) fmt::print(stderr, "dropped {}\n", line);
  auto& p = built.package;
  if (!appearance.skip) {
    const Stopwatch appearance_time;
    core::ProgressBar transfer_bar("appearance transfer");
    auto stage = stage_options;
    const auto& ranks = Ranks::world();
    stage.split.owns = [&ranks](long j) { return ranks.owns(static_cast<int>(j)); };
    stage.split.share = [&ranks](MatrixXfR& fields) { ranks.share_rows(fields); };
    const auto report = precompute::run_appearance_stage(
        p, precompute::scene_point_embedding(scene), A,
        precompute::package_node_frames(index.irfs, built.filter.kept), stage,
        [&transfer_bar](const char* stage_name, long done, long total) {
          // each of the stage's passes starts at 0: the transfers, then the nrbf's tuning per weighting
          if (done == 0) transfer_bar.restart(stage_name);
          transfer_bar.update(done, total);
        });
    transfer_bar.finish();
    if (Ranks::world().rank() == 0) {
      fmt::print(stderr, "appearance stage: {:.1f} s, peak resident memory so far {:.0f} MiB\n",
                 appearance_time.seconds(), core::resident_memory().peak_mib);
    }
    core::validate_package(p, scene.name);
    if (Ranks::world().rank() == 0) print_appearance_report(p, report);
  }
  if (Ranks::world().rank() != 0) return;  // every rank computed the package; one writes it
  core::write_package(p, package);
  fmt::print(
      "wrote {}: N = {} state nodes, {} IRFs ({} short and {} dead ends dropped), r_u = {} (error {:.4f}), "
      "r_a = {}, beta = {:.4g}\n",
      package.string(), p.portrait.nodes(), p.portrait.irf_count(), built.filter.dropped_short,
      built.filter.dropped_dead_end, p.rank_u(), core::displacement_error_at_rank(p, p.rank_u()), p.rank_a(),
      p.attributes.beta);
}

}  // namespace phasecast::precompute::tools
