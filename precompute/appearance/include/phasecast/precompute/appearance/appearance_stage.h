#pragma once
// The appearance stage of the precompute pipeline (§4): k-means of the state
// nodes in q_u, diffuse transfer on the UNREDUCED deformed mesh of each
// cluster's representative node (read from the orbit store, not U_u q_u), then
// the reduced transfer basis U_a and the NRBF q_a of every node
// (fit_appearance_model). Fills /appearance, /portrait/q_a and eps_a of a package.

#include "phasecast/core/package.h"
#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/appearance/transfer_appearance.h"
#include "phasecast/precompute/appearance/transfer_file.h"
#include "phasecast/precompute/reduction/displacement_reduction.h"
#include "phasecast/precompute/sampling/orbit_filter.h"
#include "phasecast/precompute/simulation/embedding.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

namespace phasecast::precompute {

// How the representatives' transfers are split among the processes of a run
// (docs/distributed.md): this one computes representative j when owns(j),
// then share() fills in the others' rows of the S x 48 fields, bit for bit.
struct TransferSplit {
  std::function<bool(long representative)> owns = [](long) { return true; };
  std::function<void(MatrixXfR& fields)> share = [](MatrixXfR&) {};
};

struct AppearanceStageOptions {
  int clusters = 16;       // N_a: state nodes whose transfer is computed (k-means of q_u, §4.3)
  std::uint64_t seed = 1;  // k-means++ seeding and the draw of the held-out nodes
  int held_out = 40;       // other nodes whose true transfer measures the model (0: none)
  int paper_rank = 0;      // the paper's r_a for this scene, stored for phasecast-inspect (0: none)
  TransferOptions transfer = default_stage_transfer();
  AppearanceOptions appearance;  // eps_a or fixed r_a, NRBF regularization
  TransferSplit split;           // default: this process computes every transfer
  // Called once with every transfer the stage computed, before the model is
  // fitted (so a fit that fails loses none of them); `--save-transfers`
  // writes them. Empty: not called.
  std::function<void(const StageTransfers&)> keep_transfers;

  // Interreflected, 1024 directions, 2 bounces (the transfer command's defaults):
  // about 0.1 s per cluster node on the 1242 points of cloth_door (docs/performance-transfer.md).
  static TransferOptions default_stage_transfer() {
    TransferOptions t;
    t.mode = TransferMode::interreflected;
    t.rays = 1024;
    t.bounces = 2;
    return t;
  }
};

// Throws std::invalid_argument naming --clusters, --rays, --bounces, --eps-a or --rank-a.
void check_appearance_stage_options(const AppearanceStageOptions& options);

// The orbit-store frame of every package state node: the kept IRFs of the
// store, renumbered into consecutive rows as build_package does.
std::vector<std::int64_t> package_node_frames(const IrfList& store_irfs, const std::vector<int>& kept);

// Scene points of the package mesh at one orbit-store frame: deformable points
// where the embedding puts them (`embedding`, S x V, from
// scene_point_embedding: a vertex's own position, or a render point's
// sum_i W_pi x_i + d_p), static points at rest. All in the support frame.
//   @param[in] frame  3V positions of the frame, as stored
MatrixXfR deformed_scene_points(const core::SceneMesh& mesh, const Embedding& embedding,
                                const Eigen::Ref<const Eigen::RowVectorXf>& frame);

// Transfer (S x 48) of the package's scene points at one orbit-store frame:
// normals of the deformed mesh (angle-weighted; the back side of a sheet has
// reversed triangles, hence flipped normals), then compute_transfer.
MatrixXfR transfer_at_frame(const core::SceneMesh& mesh, const Embedding& embedding,
                            const Eigen::Ref<const Eigen::RowVectorXf>& frame,
                            const TransferOptions& options);

struct AppearanceStageReport {
  KMeansResult clusters;
  std::vector<CandidateReport> candidates;   // the weightings and interpolants tried, the chosen one first
  std::optional<PairedGain> weighting_gain;  // cluster sizes against equal weights (AppearanceModel)
  // Where the served basis's truncation error lives (residual_by_part), on
  // the clusters' fields and on the held-out truth (none without held-out nodes).
  ResidualByPart clusters_residual;
  std::optional<ResidualByPart> held_out_residual;
  std::optional<BasisComparison> basis_comparison;  // AppearanceModel's
  std::optional<HeldOutRankChoice> rank_choice;     // AppearanceModel's: how --held-out-target set r_a
};

// `count` distinct state nodes of 0..N-1 that are not in `exclude`, drawn
// with std::mt19937_64(seed) (fewer when fewer remain), in draw order. The
// draw is one shuffle of all N nodes walked past the excluded ones, so the
// draws for two sets of representatives (two N_a) differ only by the
// representatives the walk meets and as many nodes at its end, and a
// shorter count draws the start of a longer one.
std::vector<std::int32_t> draw_held_out_nodes(Eigen::Index N, const std::vector<std::int32_t>& exclude,
                                              int count, std::uint64_t seed);

// Runs the stage on `package` (its portrait q_u and mesh must be final) and
// stores the model in package.appearance, package.portrait.q_a and
// package.attributes.eps_a. The true transfer of `held_out` other nodes
// measures it (fit_appearance_model). `progress(stage, done, total)` is
// called as the transfers (representatives, then held-out nodes) complete,
// as "appearance transfer", then per grid point of the NRBF's tuning, as
// "appearance nrbf tuning" (from 0 again for each weighting tried).
//   @param[in] orbits       the store the package was reduced from
//   @param[in] node_frames  package_node_frames(...) of that reduction
// Throws std::invalid_argument for bad options (N_a above the node count
// included) and OrbitStoreError when a frame cannot be read.
AppearanceStageReport run_appearance_stage(core::ScenePackage& package, const Embedding& embedding,
                                           const OrbitDisplacementSource& orbits,
                                           const std::vector<std::int64_t>& node_frames,
                                           const AppearanceStageOptions& options,
                                           const std::function<void(const char*, long, long)>& progress = {});

}  // namespace phasecast::precompute
