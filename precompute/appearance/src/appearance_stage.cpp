#include "phasecast/precompute/appearance/appearance_stage.h"
#include "phasecast/core/mesh_geometry.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

namespace phasecast::precompute {

void check_appearance_stage_options(const AppearanceStageOptions& o) {
  if (o.clusters < 1)
    throw std::invalid_argument(fmt::format("appearance: expected --clusters >= 1, got {}", o.clusters));
  if (o.held_out < 0)
    throw std::invalid_argument(fmt::format("appearance: expected --held-out >= 0, got {}", o.held_out));
  if (o.transfer.rays < 1 || o.transfer.rays > (1 << 20))
    throw std::invalid_argument(
        fmt::format("appearance: expected --rays in 1..1048576, got {}", o.transfer.rays));
  if (o.transfer.bounces < 0)
    throw std::invalid_argument(
        fmt::format("appearance: expected --bounces >= 0, got {}", o.transfer.bounces));
  const double eps = o.appearance.reduction.eps_a;
  if (!(std::isfinite(eps) && eps > 0 && eps < 1))
    throw std::invalid_argument(fmt::format("appearance: expected --eps-a in (0, 1), got {}", eps));
  if (o.appearance.reduction.rank < 0)
    throw std::invalid_argument(fmt::format("appearance: expected --rank-a >= 0 (0: use --eps-a), got {}",
                                            o.appearance.reduction.rank));
  if (const double target = o.appearance.held_out_target; target != 0) {
    if (!(target > 0 && target < 1))
      throw std::invalid_argument(
          fmt::format("appearance: expected --held-out-target in (0, 1), got {}", target));
    if (o.appearance.reduction.rank > 0)
      throw std::invalid_argument(
          "appearance: --held-out-target and --rank-a both fix r_a: give one of them");
    if (o.held_out < 2)
      throw std::invalid_argument(fmt::format(
          "appearance: --held-out-target is measured at the picking half of the held-out nodes: expected "
          "--held-out >= 2, got {}",
          o.held_out));
  }
  validate_transfer_options(o.transfer);
}

std::vector<std::int64_t> package_node_frames(const IrfList& irfs, const std::vector<int>& kept) {
  std::vector<std::int64_t> frames;
  for (int i : kept) {
    const auto k = static_cast<size_t>(i);
    for (std::int32_t f = 0; f < irfs.length[k]; ++f) frames.push_back(irfs.start[k] + f);
  }
  return frames;
}

MatrixXfR deformed_scene_points(const core::SceneMesh& mesh, const Embedding& embedding,
                                const Eigen::Ref<const Eigen::RowVectorXf>& frame) {
  const VertexEmbedding& W = embedding.weights;
  if (W.rows() != mesh.points() || 3 * W.cols() != frame.size()) {
    throw std::invalid_argument(
        fmt::format("appearance: embedding of {} points in {} vertices, but the mesh has {} points and a "
                    "frame {} vertices",
                    W.rows(), W.cols(), mesh.points(), frame.size() / 3));
  }
  const MatrixXfR moved = embed_positions(embedding, frame.transpose());
  MatrixXfR x = mesh.rest_positions;
  for (Eigen::Index p = 0; p < x.rows(); ++p) {
    if (!embeds(W, p) || !mesh.deformable[static_cast<size_t>(p)]) continue;
    for (int k = 0; k < 3; ++k) x(p, k) = moved(3 * p + k, 0);
  }
  return x;
}

MatrixXfR transfer_at_frame(const core::SceneMesh& mesh, const Embedding& embedding,
                            const Eigen::Ref<const Eigen::RowVectorXf>& frame,
                            const TransferOptions& options) {
  const MatrixXfR x = deformed_scene_points(mesh, embedding, frame);
  const MatrixXfR n = core::vertex_normals(x, mesh.triangles);
  return compute_transfer(x, mesh.triangles, n, options);  // §4.1, on the unreduced mesh
}

std::vector<std::int32_t> draw_held_out_nodes(Eigen::Index N, const std::vector<std::int32_t>& exclude,
                                              int count, std::uint64_t seed) {
  std::vector<std::uint8_t> excluded(static_cast<size_t>(N), 0);
  for (auto n : exclude)
    if (n >= 0 && n < N) excluded[static_cast<size_t>(n)] = 1;
  // One shuffle of all N nodes whatever `exclude` is, walked in order past the
  // excluded ones: another set of clusters (another N_a) then reports on the
  // same nodes but the few that became representatives, so figures compare.
  // Partial Fisher-Yates; mt19937_64's output is fixed by the standard, and
  // the modulo (bias < 2^-40 here) is ours, so every machine draws the same.
  std::vector<std::int32_t> order(static_cast<size_t>(N));
  std::iota(order.begin(), order.end(), 0);
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  std::vector<std::int32_t> drawn;
  const size_t wanted = static_cast<size_t>(std::max(count, 0));
  for (size_t i = 0; i < order.size() && drawn.size() < wanted; ++i) {
    std::swap(order[i], order[i + rng() % (order.size() - i)]);
    if (!excluded[static_cast<size_t>(order[i])]) drawn.push_back(order[i]);
  }
  return drawn;
}

namespace {

// Hands every transfer of the stage to options.keep_transfers; `fields` is
// moved in and back, not copied (it can hold gigabytes).
void keep_transfers(const core::ScenePackage& pkg, const KMeansResult& clusters,
                    const std::vector<std::int32_t>& nodes, MatrixXfR& fields,
                    const AppearanceStageOptions& o) {
  StageTransfers t;
  t.scene = pkg.attributes.scene;
  t.nodes = nodes;
  const size_t Na = clusters.representatives.size(), H = nodes.size() - Na;
  t.roles.assign(Na, TransferRole::representative);
  t.roles.resize(Na + held_out_picking_count(H), TransferRole::picking);
  t.roles.resize(nodes.size(), TransferRole::reported);
  t.q_u.resize(static_cast<Eigen::Index>(nodes.size()), pkg.portrait.q_u.cols());
  for (size_t j = 0; j < nodes.size(); ++j)
    t.q_u.row(static_cast<Eigen::Index>(j)) = pkg.portrait.q_u.row(nodes[j]);
  t.labels = clusters.labels;
  t.rest_positions = pkg.mesh.rest_positions;
  t.deformable = pkg.mesh.deformable;
  t.rays = o.transfer.rays;
  t.bounces = o.transfer.mode == TransferMode::interreflected ? o.transfer.bounces : 0;
  t.fields = std::move(fields);
  o.keep_transfers(t);
  fields = std::move(t.fields);
}

}  // namespace

AppearanceStageReport run_appearance_stage(core::ScenePackage& pkg, const Embedding& embedding,
                                           const OrbitDisplacementSource& orbits,
                                           const std::vector<std::int64_t>& node_frames,
                                           const AppearanceStageOptions& o,
                                           const std::function<void(const char*, long, long)>& progress) {
  check_appearance_stage_options(o);
  const MatrixXfR& q_u = pkg.portrait.q_u;
  const Eigen::Index N = q_u.rows();
  if (static_cast<Eigen::Index>(node_frames.size()) != N) {
    throw std::invalid_argument(
        fmt::format("appearance: {} node frames for {} state nodes", node_frames.size(), N));
  }
  if (o.clusters > N) {
    throw std::invalid_argument(fmt::format(
        "appearance: expected --clusters in 1..{} (the state nodes of the package), got {}", N, o.clusters));
  }
  AppearanceStageReport report;
  report.clusters = kmeans(q_u, {o.clusters, o.seed, 100});  // §4.3: N_a clusters of the nodes
  const auto& representatives = report.clusters.representatives;
  HeldOutTruth held_out;
  held_out.nodes = draw_held_out_nodes(N, representatives, o.held_out, o.seed);
  // One list of transfers: the N_a representatives, then the held-out nodes.
  std::vector<std::int32_t> nodes = representatives;
  nodes.insert(nodes.end(), held_out.nodes.begin(), held_out.nodes.end());
  const auto count = static_cast<long>(nodes.size());
  MatrixXfR fields(count, core::kTransferPerPoint * pkg.mesh.points());
  TransferOptions transfer = o.transfer;
  transfer.progress = nullptr;  // one tick per node is the stage's progress
  long own = 0;                 // this process's share of the transfers
  for (long j = 0; j < count; ++j) own += o.split.owns(j) ? 1 : 0;
  if (progress) progress("appearance transfer", 0, own);
  for (long j = 0, done = 0; j < count; ++j) {
    if (!o.split.owns(j)) continue;
    MatrixXfR frame;
    orbits.read_frames(node_frames[static_cast<size_t>(nodes[static_cast<size_t>(j)])], 1, frame);
    const MatrixXfR T = transfer_at_frame(pkg.mesh, embedding, frame.row(0), transfer);
    fields.row(j) = Eigen::Map<const Eigen::RowVectorXf>(T.data(), T.size());  // S x 48 row-major = 48S
    if (progress) progress("appearance transfer", ++done, own);
  }
  o.split.share(fields);
  const auto Na = static_cast<Eigen::Index>(representatives.size());
  if (o.keep_transfers) keep_transfers(pkg, report.clusters, nodes, fields, o);
  held_out.fields = fields.bottomRows(count - Na);
  AppearanceOptions fit = o.appearance;
  fit.progress = progress;
  AppearanceModel model =
      fit_appearance_model(q_u, report.clusters, fields.topRows(Na), fit, held_out);  // §4.2, §4.3
  report.candidates = std::move(model.candidates);
  report.weighting_gain = model.weighting_gain;
  report.basis_comparison = model.basis_comparison;
  report.rank_choice = model.rank_choice;
  model.appearance.paper_rank = o.paper_rank;
  model.appearance.transfer_rays = o.transfer.rays;
  model.appearance.transfer_bounces =
      o.transfer.mode == TransferMode::interreflected ? o.transfer.bounces : 0;
  pkg.appearance = std::move(model.appearance);
  const auto& a = *pkg.appearance;
  report.clusters_residual =
      residual_by_part(fields.topRows(Na), a.mean_transfer, a.U_a, pkg.mesh.deformable);
  if (held_out.fields.rows() > 0)
    report.held_out_residual = residual_by_part(held_out.fields, a.mean_transfer, a.U_a, pkg.mesh.deformable);
  pkg.portrait.q_a = std::move(model.q_a);
  const bool fixed_rank = o.appearance.reduction.rank > 0 || o.appearance.held_out_target > 0;
  pkg.attributes.eps_a = fixed_rank ? 0.0 : o.appearance.reduction.eps_a;
  return report;
}

}  // namespace phasecast::precompute
