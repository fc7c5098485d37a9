// The appearance stage (§4) as phasecast-precompute run/reduce perform it on
// the tiny cloth_door: a package with /appearance that validates and that
// inspect reports, transfer taken on the unreduced orbit-store meshes of the
// cluster nodes, both sides of the cloth, determinism and one-line errors.

#include "phasecast/precompute/appearance/appearance_stage.h"
#include "phasecast/core/mesh_geometry.h"
#include "phasecast/core/package.h"
#include "phasecast/core/package_summary.h"
#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/appearance/transfer_file.h"
#include "phasecast/precompute/package/package_builder.h"
#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/simulation/scene.h"
#include "run_tool.h"
#include "scene_files.h"
#include "source_tree.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace phasecast {
namespace {

using testing::run_tool;
using testing::scratch_dir;
using testing::tiny_scene_path;

// Small sampling, every IRF kept (so package node n is orbit-store frame n),
// 4 clusters, a coarse direction set: seconds on 2 cores.
// A sample this thin leaves an entry without IRFs, which run would refuse (not what these tests are about).
const std::vector<std::string> kSample = {"--chains", "2", "--irfs-per-chain",       "3",
                                          "--seed",   "4", "--allow-missing-entries"};
const std::vector<std::string> kReduce = {"--max-rank", "20", "--dead-end-fraction", "0", "--clusters", "4",
                                          "--rays",     "64", "--bounces",           "1", "--held-out", "6"};

// The tiny door (0.8 x 2 x 0.04 m) in 0.2 m cells: faces of 4 x 10, 4 x 1 and 10 x 1 cells.
constexpr int kDoorPoints = 2 * (5 * 11) + 2 * (5 * 2) + 2 * (11 * 2);
constexpr int kDoorTriangles = 2 * 2 * (4 * 10 + 4 * 1 + 10 * 1);

// `head`, then the sampling options (run only) and the reduce/appearance
// options, where `overrides` (flag, value pairs) replace or extend them.
std::vector<std::string> args(std::vector<std::string> head, std::vector<std::string> overrides = {}) {
  const bool run = head.front() == "run";
  if (run) head.insert(head.end(), kSample.begin(), kSample.end());
  std::vector<std::string> tail = kReduce;
  for (size_t i = 0; i + 1 < overrides.size(); i += 2) {
    auto at = std::find(tail.begin(), tail.end(), overrides[i]);
    if (at != tail.end()) {
      *(at + 1) = overrides[i + 1];
    } else {
      tail.push_back(overrides[i]);
      tail.push_back(overrides[i + 1]);
    }
  }
  if (overrides.size() % 2 == 1) tail.push_back(overrides.back());  // a trailing flag
  head.insert(head.end(), tail.begin(), tail.end());
  return head;
}

bool one_line(const std::string& s) {
  return !s.empty() && s.find('\n') == s.size() - 1;
}

// The last line of a tool's stderr (earlier lines are stage progress).
std::string last_line(const std::string& s) {
  const auto end = s.empty() || s.back() != '\n' ? s.size() : s.size() - 1;
  const auto begin = s.rfind('\n', end == 0 ? 0 : end - 1);
  return s.substr(begin == std::string::npos ? 0 : begin + 1,
                  end - (begin == std::string::npos ? 0 : begin + 1));
}

// Runs `run` on the tiny scene into dir/name.h5 and returns the package path.
std::string run_tiny(const std::string& dir_name, const std::vector<std::string>& extra = {}) {
  const auto dir = scratch_dir(dir_name);
  const auto pkg = (dir / "tiny.h5").string();
  const auto r =
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg}, extra));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return pkg;
}

TEST(AppearanceStage, RunWritesAnAppearanceThatInspectShows) {
  const auto dir = scratch_dir("appearance_run");
  const auto pkg = (dir / "tiny.h5").string();
  const auto r = run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("appearance transfer: 10/10"), std::string::npos) << r.err;  // 4 clusters, 6 held out
  EXPECT_NE(r.err.find("appearance nrbf tuning: 25/25"), std::string::npos) << r.err;  // 5 widths x 5 lambdas
  EXPECT_NE(r.out.find("appearance: N_a = 4 clusters"), std::string::npos) << r.out;
  const auto p = core::read_package(pkg);  // validates
  ASSERT_TRUE(p.appearance.has_value());
  EXPECT_GE(p.rank_a(), 1);
  EXPECT_LE(p.rank_a(), 3);  // at most N_a - 1 centred fields
  EXPECT_EQ(p.appearance->clusters(), 4);
  EXPECT_EQ(p.portrait.q_a.rows(), p.portrait.nodes());
  EXPECT_EQ(p.portrait.q_a.cols(), p.rank_a());
  EXPECT_EQ(p.appearance->mean_transfer.size(), 48 * p.mesh.points());
  EXPECT_TRUE(p.portrait.q_a.allFinite());
  EXPECT_GT(p.attributes.eps_a, 0.0);
  const auto inspect = run_tool("phasecast-inspect", {pkg});
  ASSERT_EQ(inspect.exit_code, 0) << inspect.err;
  EXPECT_NE(inspect.out.find(fmt::format(
                "appearance   r_a = {}, N_a = 4 clusters, at r_a: relative l2 error sigma_{{r+1}}/sigma_1 = ",
                p.rank_a())),
            std::string::npos)
      << inspect.out;
  EXPECT_NE(inspect.out.find("held-out truth (3 other nodes): error "), std::string::npos) << inspect.out;
  EXPECT_NE(inspect.out.find("held-out in the paper's relErr (relative l2 norm over those nodes): "),
            std::string::npos)
      << inspect.out;
  EXPECT_EQ(p.appearance->paper_rank, 12);  // stored; printed only when r_a = 12 is within N_a
  EXPECT_NE(inspect.out.find(fmt::format("transfer sampled with {} rays, {} interreflection bounces",
                                         p.appearance->transfer_rays, p.appearance->transfer_bounces)),
            std::string::npos)
      << inspect.out;
  EXPECT_GE(p.appearance->transfer_rays, 1);  // the tiny scene's
  ASSERT_TRUE(p.appearance->held_out);
  const core::HeldOutFigures& h = *p.appearance->held_out;
  ASSERT_TRUE(h.l2_floor_of_variation && h.l2_of_variation_spread);  // every figure measured
  EXPECT_GT(h.total, 0.0f);                                          // nodes the model never saw
  EXPECT_NE(
      inspect.out.find(fmt::format("of their own variation over resampled nodes (10th-90th percentile): "
                                   "relative l2 {:.3g}-{:.3g}%",
                                   100 * h.l2_of_variation_spread->p10, 100 * h.l2_of_variation_spread->p90)),
      std::string::npos)
      << inspect.out;
  EXPECT_NE(inspect.out.find(fmt::format("over resampled nodes (10th-90th percentile): {:.3g}-{:.3g}%",
                                         100 * h.l2_total_spread->p10, 100 * h.l2_total_spread->p90)),
            std::string::npos)
      << inspect.out;
  // The paper's-metric figures reach the JSON that bench/paper_tables.py reads.
  const auto json = run_tool("phasecast-inspect", {pkg, "--json"});
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const auto held_out = nlohmann::json::parse(json.out)["held_out"];
  EXPECT_NEAR(held_out["l2_total"].get<double>(), *h.l2_total, 1e-6);
  EXPECT_NEAR(held_out["l2_truncation"].get<double>(), *h.l2_truncation, 1e-6);
  EXPECT_NEAR(held_out["clusters_l2_truncation"].get<double>(), *h.clusters_l2_truncation, 1e-6);
  // 3 reported nodes and r_a up to 3: the floor may be 0 here. Its value is
  // tested in appearance_test.cpp; this checks that it reaches the package,
  // inspect and the JSON.
  EXPECT_NEAR(held_out["l2_floor"].get<double>(), *h.l2_floor, 1e-6);
  EXPECT_LE(*h.l2_floor, *h.l2_truncation + 1e-6);
  // Fig. 12 out of sample reaches the package, the run's output and inspect alike.
  const VectorXf& curve = h.truncation_curve;
  ASSERT_GE(curve.size(), p.rank_a());
  ASSERT_LE(curve.size(), 3);
  EXPECT_NEAR(curve[p.rank_a() - 1], *h.l2_truncation, 1e-4);
  const std::string curve_line =
      core::held_out_curve_text(std::vector<double>(curve.data(), curve.data() + curve.size()), p.rank_a(),
                                12, *h.clusters_l2_truncation);
  EXPECT_NE(r.out.find("appearance: held-out truncation by rank (Fig. 12 out of sample, relative l2): " +
                       curve_line + "\n"),
            std::string::npos)
      << r.out;
  EXPECT_NE(inspect.out.find(
                "held-out truncation by rank (Fig. 12 out of sample, relative l2): " + curve_line + "\n"),
            std::string::npos)
      << inspect.out;
  EXPECT_NE(inspect.out.find(fmt::format("the least any rank-{} model about M-bar reaches at those nodes "
                                         "(sigma_{{r+1}}/sigma_1 of their M - M-bar): {:.3g}%",
                                         p.appearance->U_a.cols(), 100 * *h.l2_floor)),
            std::string::npos)
      << inspect.out;
  EXPECT_NE(inspect.out.find("the clusters' own truncation measured alike (relative l2 over 3 of them"),
            std::string::npos)
      << inspect.out;
  // The figures of the nodes' own variation, and the weighting the picking half kept.
  EXPECT_NEAR(held_out["of_variation"].get<double>(), *h.of_variation, 1e-6);
  EXPECT_NEAR(held_out["l2_of_variation"].get<double>(), *h.l2_of_variation, 1e-6);
  EXPECT_NEAR(held_out["l2_floor_of_variation"].get<double>(), *h.l2_floor_of_variation, 1e-6);
  EXPECT_NE(
      inspect.out.find(fmt::format("of the nodes' own variation |M - their mean| (moves with no model): "
                                   "error {:.3g}%, relative l2 {:.3g}%",
                                   100 * *h.of_variation, 100 * *h.l2_of_variation)),
      std::string::npos)
      << inspect.out;
  EXPECT_EQ(nlohmann::json::parse(json.out)["transfer_weighting"], p.appearance->transfer_weighting);
  // The run printed the paired comparison of the two weightings; its verdict is the stored one.
  const auto verdict = r.out.find("appearance: cluster sizes leave ");
  ASSERT_NE(verdict, std::string::npos) << r.out;
  const bool weighted = r.out.find("beyond it, cluster sizes kept", verdict) != std::string::npos;
  EXPECT_EQ(p.appearance->transfer_weighting, weighted ? "cluster size" : "equal") << r.out;
  EXPECT_NE(inspect.out.find(fmt::format("transfer fields weighted {}", p.appearance->transfer_weighting)),
            std::string::npos)
      << inspect.out;
  // Where the truncation error lives, on the clusters and on the held-out nodes. With equal weights
  // the clusters' figure is the package's Frobenius error curve at r_a (Fig. 12).
  const std::string lives =
      "where the truncation error lives (share of the variation about M-bar / of what "
      "U_a leaves of it (relative error)): clusters ";
  const auto at = r.out.find(lives);
  ASSERT_NE(at, std::string::npos) << r.out;
  const double clusters = std::stod(r.out.substr(at + lives.size(), 6));
  if (p.appearance->transfer_weighting == "equal") {
    EXPECT_NEAR(clusters, p.appearance->rel_error[p.rank_a() - 1], 1e-4) << r.out;
  }
  EXPECT_NE(r.out.find(": deformable points ", at), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\n  held-out nodes ", at), std::string::npos) << r.out;
  // The basis of the picking half's 3 fields is compared when they resolve r_a directions.
  const bool compared =
      r.out.find(fmt::format("a rank-{} basis of the picking half's own 3 fields (random states) ",
                             p.rank_a())) != std::string::npos;
  EXPECT_EQ(compared, p.rank_a() < 3) << r.out;
  EXPECT_NE(inspect.out.find(fmt::format("interpolant {}", p.appearance->interpolant)), std::string::npos)
      << inspect.out;
}

// At r_a = 1 the picking half's 3 fields resolve a basis of the served rank:
// the run prints both truncations, the served one part of the stored total.
// The interpolant asked for by name is the one stored.
TEST(AppearanceStage, RunComparesTheClustersBasisWithOneOfThePickingHalf) {
  const auto dir = scratch_dir("appearance_drawn_basis");
  const auto pkg = (dir / "tiny.h5").string();
  const auto r =
      run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg},
                                            {"--rank-a", "1", "--interpolant", "affine-knn-slope"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto p = core::read_package(pkg);
  ASSERT_EQ(p.rank_a(), 1);
  EXPECT_EQ(p.appearance->interpolant, "affine-knn-slope");
  const std::string served = "(Frobenius / l2): the 4 clusters' basis ";
  const auto at = r.out.find(served);
  ASSERT_NE(at, std::string::npos) << r.out;
  EXPECT_NE(r.out.find("a rank-1 basis of the picking half's own 3 fields (random states) ", at),
            std::string::npos)
      << r.out;
  const double truncation = std::stod(r.out.substr(at + served.size(), 6));
  EXPECT_GT(truncation, 0);
  EXPECT_LE(truncation, *p.appearance->held_out->of_variation + 1e-4) << r.out;  // part of the total error
  // The paired verdict: its direction and one of its three readings.
  const bool more = r.out.find("% more squared error, noise ", at) != std::string::npos;
  const bool less = r.out.find("% less squared error, noise ", at) != std::string::npos;
  EXPECT_NE(more, less) << r.out;
  const auto verdict = [&](const char* v) { return r.out.find(v, at) != std::string::npos; };
  EXPECT_EQ(verdict("the drawn basis is the better one") + verdict("the clusters' basis is the better one") +
                verdict("within noise of each other"),
            1)
      << r.out;
  // 3 drawn fields against 4 clusters: the line says it is not like with like.
  EXPECT_NE(r.out.find("(from fewer fields than the 4 clusters: --held-out 8 compares like with like)", at),
            std::string::npos)
      << r.out;
}

// --held-out-target through run: the line names the rank the picking half
// chose, the package holds it, with eps_a 0 (the rank was fixed), and the
// reported figures are still those of the half that never chose.
TEST(AppearanceStage, HeldOutTargetChoosesRaAtThePickingHalf) {
  const auto dir = scratch_dir("appearance_held_out_target");
  const auto pkg = (dir / "tiny.h5").string();
  const auto r = run_tool("phasecast-precompute",
                          args({"run", tiny_scene_path().string(), "-o", pkg}, {"--held-out-target", "0.6"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto p = core::read_package(pkg);
  const std::string line = fmt::format(
      "appearance: r_a = {}, the least rank whose truncation alone at the "
      "picking half's 3 nodes (relative l2, equal weights) is at most 0.6000",
      p.rank_a());
  const bool reached = r.out.find(line) != std::string::npos;
  const bool not_reached = r.out.find(
                               "appearance: no rank of the clusters brings the truncation at the picking "
                               "half's 3 nodes to 0.6000") != std::string::npos;
  EXPECT_NE(reached, not_reached) << r.out;
  EXPECT_EQ(p.attributes.eps_a, 0.0);
  ASSERT_TRUE(p.appearance->held_out);
  ASSERT_GE(p.appearance->held_out->truncation_curve.size(), p.rank_a());
}

// --save-transfers keeps what the model was made from and measured against:
// each row is the transfer of its node's stored mesh (computed again here),
// the representatives' mean is M-bar (equal weights), and U_a leaves of the
// reported rows the truncation the package reports.
TEST(AppearanceStage, SaveTransfersKeepsEveryTransferOfTheStage) {
  const auto dir = scratch_dir("appearance_save_transfers");
  const auto saved = (dir / "transfers.h5").string();
  const auto pkg_path =
      run_tiny("appearance_save_transfers_run", {"--save-transfers", saved, "--transfer-weighting", "equal"});
  const auto p = core::read_package(pkg_path);
  const auto& a = *p.appearance;
  const auto t = precompute::read_stage_transfers(saved);
  const size_t Na = a.cluster_nodes.size(), H = 6;
  ASSERT_EQ(Na, 4u);
  ASSERT_EQ(t.nodes.size(), Na + H);
  using Role = precompute::TransferRole;
  for (size_t j = 0; j < t.nodes.size(); ++j) {
    const Role expected = j < Na ? Role::representative : j < Na + 3 ? Role::picking : Role::reported;
    EXPECT_EQ(t.roles[j], expected) << j;
    if (j < Na) {
      EXPECT_EQ(t.nodes[j], a.cluster_nodes[j]);
    } else if (j >= Na + 3) {
      EXPECT_EQ(t.nodes[j], a.held_out->nodes[j - Na - 3]);
    }
    EXPECT_TRUE(t.q_u.row(static_cast<Eigen::Index>(j)) == p.portrait.q_u.row(t.nodes[j])) << j;
  }
  ASSERT_EQ(t.labels.size(), static_cast<size_t>(p.portrait.nodes()));
  for (size_t k = 0; k < Na; ++k) EXPECT_EQ(t.labels[t.nodes[k]], static_cast<int>(k));  // in its own cluster
  // The picking half: the first held-out nodes of the stage's draw (--cluster-seed 1).
  const auto drawn = precompute::draw_held_out_nodes(p.portrait.nodes(), a.cluster_nodes, 6, 1);
  EXPECT_EQ(std::vector<std::int32_t>(t.nodes.begin() + 4, t.nodes.end()), drawn);
  EXPECT_TRUE(t.rest_positions == p.mesh.rest_positions);
  EXPECT_EQ(t.deformable, p.mesh.deformable);
  EXPECT_EQ(t.scene, p.attributes.scene);
  EXPECT_EQ(t.rays, 64);
  EXPECT_EQ(t.bounces, 1);

  // A representative and a reported node, computed again from the orbit store.
  const auto store = precompute::read_orbit_store(pkg_path + ".work/orbits.h5");
  const auto scene = precompute::load_scene_file(tiny_scene_path());
  precompute::TransferOptions options;
  options.mode = precompute::TransferMode::interreflected;
  options.rays = 64;
  options.bounces = 1;
  options.point_albedo = precompute::scene_point_albedo(scene);
  for (const size_t j : {size_t{0}, Na + H - 1}) {
    const MatrixXfR again = precompute::transfer_at_frame(p.mesh, precompute::scene_point_embedding(scene),
                                                          store.positions.row(t.nodes[j]), options);
    EXPECT_TRUE(Eigen::Map<const Eigen::RowVectorXf>(again.data(), again.size()) ==
                t.fields.row(static_cast<Eigen::Index>(j)))
        << "row " << j;
  }

  const Eigen::VectorXf mean = t.fields.topRows(static_cast<Eigen::Index>(Na)).colwise().mean().transpose();
  EXPECT_LT((mean - a.mean_transfer).norm(), 1e-5f * a.mean_transfer.norm());
  const MatrixXfR centred = t.fields.bottomRows(3).rowwise() - a.mean_transfer.transpose();
  const MatrixXfR residual = centred - (centred * a.U_a) * a.U_a.transpose();
  EXPECT_NEAR(residual.norm() / centred.norm(), a.held_out->truncation, 1e-4);
}

TEST(AppearanceStage, TransfersFileReaderNamesWhatIsWrong) {
  const auto dir = scratch_dir("appearance_transfers_reader");
  const auto missing = dir / "none.h5";
  EXPECT_THROW(
      {
        try {
          precompute::read_stage_transfers(missing);
        } catch (const std::runtime_error& e) {
          EXPECT_EQ(std::string(e.what()), missing.string() + ": no such transfers file");
          throw;
        }
      },
      std::runtime_error);
  // A transfer file of the standalone tool is another format.
  const auto other = dir / "transfer.h5";
  precompute::TransferFile file;
  file.positions = MatrixXfR::Zero(2, 3);
  file.normals = MatrixXfR::Zero(2, 3);
  file.transfer = MatrixXfR::Zero(2, 48);
  precompute::write_transfer_file(file, other);
  try {
    precompute::read_stage_transfers(other);
    ADD_FAILURE() << "read a transfer file as a transfers file";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()),
              other.string() + ": /@format: expected phasecast-stage-transfers (a file of --save-transfers)");
  }
  // Inconsistent sizes are refused before anything is written.
  precompute::StageTransfers t;
  t.nodes = {0, 1};
  t.roles = {precompute::TransferRole::representative};
  t.rest_positions = MatrixXfR::Zero(1, 3);
  t.deformable = {1};
  try {
    precompute::write_stage_transfers(t, dir / "bad.h5");
    ADD_FAILURE() << "wrote inconsistent sizes";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(
        std::string(e.what()),
        (dir / "bad.h5").string() +
            ": a transfers file needs one role, field (48S) and q_u row per node and S x 3 rest points; "
            "got 2 nodes, 1 roles, 0 x 0 fields, 0 q_u rows, 1 x 3 rest points, 1 deformable flags");
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.h5"));
}

TEST(AppearanceStage, TransferIsTakenOnTheUnreducedMeshOfEachClusterNode) {
  // Full rank (r_a = N_a - 1) so every cluster field lies in mean + span(U_a).
  const auto pkg_path = run_tiny("appearance_unreduced", {"--eps-a", "1e-7"});
  const auto p = core::read_package(pkg_path);
  ASSERT_TRUE(p.appearance.has_value());
  const auto store = precompute::read_orbit_store(pkg_path + ".work/orbits.h5");
  ASSERT_EQ(p.portrait.nodes(), store.frames());  // nothing dropped: node n is frame n
  const auto scene = precompute::load_scene_file(tiny_scene_path());
  const int V = scene.model.vertices();
  ASSERT_EQ(p.mesh.points(), 2 * V + kDoorPoints);

  precompute::TransferOptions options;
  options.mode = precompute::TransferMode::interreflected;
  options.rays = 64;
  options.bounces = 1;
  options.point_albedo = precompute::scene_point_albedo(scene);  // blue cloth, wooden door
  const auto& a = *p.appearance;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(a.mean_transfer.size());
  for (int node : a.cluster_nodes) {
    // The mesh built here by hand from the stored frame, not from U_u q_u: front
    // cloth at the simulated positions, back cloth at the same, board at rest.
    MatrixXfR x = p.mesh.rest_positions;
    for (int v = 0; v < V; ++v) {
      for (int k = 0; k < 3; ++k) x(v, k) = x(V + v, k) = store.positions(node, 3 * v + k);
    }
    const MatrixXfR direct =
        precompute::compute_transfer(x, p.mesh.triangles, core::vertex_normals(x, p.mesh.triangles), options);
    const MatrixXfR staged = precompute::transfer_at_frame(p.mesh, precompute::scene_point_embedding(scene),
                                                           store.positions.row(node), options);
    EXPECT_TRUE(direct == staged) << "node " << node;
    const Eigen::VectorXf field = Eigen::Map<const Eigen::VectorXf>(direct.data(), direct.size());
    mean += field.cast<double>();
    // Reconstructed by the package basis: M^j = M-bar + U_a U_a^T (M^j - M-bar) (§4.2, full rank).
    const Eigen::VectorXf centred = field - a.mean_transfer;
    const Eigen::VectorXf residual = centred - a.U_a * (a.U_a.transpose() * centred);
    EXPECT_LT(residual.norm(), 1e-3 * centred.norm() + 1e-6f) << "node " << node;
  }
  mean /= static_cast<double>(a.cluster_nodes.size());
  EXPECT_LT((mean.cast<float>() - a.mean_transfer).norm(), 1e-5 * a.mean_transfer.norm());

  // The reduced mesh of a cluster node is not the stored one (r_u truncates), so
  // the check above distinguishes the two.
  const int node = a.cluster_nodes[0];
  const Eigen::VectorXf reduced =
      p.reduction.mean_shape + p.reduction.U_u * p.portrait.q_u.row(node).transpose();
  const Eigen::VectorXf stored = store.positions.row(node).transpose();
  EXPECT_GT((reduced.head(3 * V) - stored).norm(), 0.0f);
}

TEST(AppearanceStage, DefaultScenesAreColouredWithTessellatedProps) {
  const auto cloth = precompute::load_scene_file(phasecast::testing::scenes_dir() / "cloth_door.toml");
  EXPECT_EQ(cloth.bodies.at(0).albedo, Eigen::Vector3d(0.12, 0.3, 0.75));
  EXPECT_EQ(cloth.props.at(0).albedo, Eigen::Vector3d(0.62, 0.42, 0.24));
  EXPECT_EQ(cloth.appearance.clusters, 64);
  EXPECT_EQ(cloth.appearance.paper_rank_a, 12);
  const auto W = precompute::scene_point_embedding(cloth).weights;
  int door = 0;  // static points: moved by no vertex
  for (Eigen::Index p = 0; p < W.rows(); ++p) door += !precompute::embeds(W, p);
  EXPECT_GE(door, 2000);  // dense enough to receive the cloth's shadow
}

TEST(AppearanceStage, ClothHasTwoSidesSharingTheirVertexRows) {
  const auto scene = precompute::load_scene_file(tiny_scene_path());
  const int V = scene.model.vertices();
  const auto F = scene.model.surface.rows();
  const auto m = precompute::scene_mesh(scene);
  ASSERT_EQ(m.points(), 2 * V + kDoorPoints);
  ASSERT_EQ(m.triangles.rows(), 2 * F + kDoorTriangles);
  for (int v = 0; v < V; ++v) {
    EXPECT_TRUE(m.rest_positions.row(V + v) == m.rest_positions.row(v));
    EXPECT_TRUE(m.normals.row(V + v) == -m.normals.row(v));
    EXPECT_EQ(m.deformable[static_cast<size_t>(V + v)], 1);
  }
  for (Eigen::Index t = 0; t < F; ++t) {  // reversed winding over the copies
    EXPECT_EQ(m.triangles(F + t, 0), m.triangles(t, 0) + V);
    EXPECT_EQ(m.triangles(F + t, 1), m.triangles(t, 2) + V);
    EXPECT_EQ(m.triangles(F + t, 2), m.triangles(t, 1) + V);
  }
  const auto W =
      precompute::scene_point_embedding(scene).weights;  // the back of vertex 3 moves with vertex 3 alone
  ASSERT_EQ(W.rows(), m.points());
  EXPECT_EQ(W.row(V + 3).nonZeros(), 1);
  EXPECT_EQ(W.coeff(V + 3, 3), 1.0);
  EXPECT_FALSE(precompute::embeds(W, m.points() - 1));

  // Every door point lies on the board's surface, at a 0.2 m grid step or a face edge.
  const auto& door = scene.model.obstacles.at(0);
  for (Eigen::Index q = 2 * V; q < m.points(); ++q) {
    const Eigen::Vector3d x = m.rest_positions.row(q).cast<double>().transpose();
    int on_face = 0;
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(x[k], door.min[k] - 1e-6);
      EXPECT_LE(x[k], door.max[k] + 1e-6);
      on_face += std::abs(x[k] - door.min[k]) < 1e-6 || std::abs(x[k] - door.max[k]) < 1e-6;
    }
    EXPECT_GE(on_face, 1) << "point " << q;
  }
  // Albedo: the blue cloth on both sides, the wooden door.
  const MatrixXfR rho = precompute::scene_point_albedo(scene);
  ASSERT_EQ(rho.rows(), m.points());
  EXPECT_TRUE(rho.row(0).isApprox(Eigen::RowVector3f(0.12f, 0.3f, 0.75f)));
  EXPECT_TRUE(rho.row(V + 3).isApprox(Eigen::RowVector3f(0.12f, 0.3f, 0.75f)));
  EXPECT_TRUE(rho.row(m.points() - 1).isApprox(Eigen::RowVector3f(0.62f, 0.42f, 0.24f)));

  const auto p = core::read_package(run_tiny("appearance_two_sides"));
  const auto& U = p.reduction.U_u;
  EXPECT_TRUE(U.middleRows(3 * V, 3 * V) == U.topRows(3 * V));
  EXPECT_TRUE(p.reduction.mean_shape.segment(3 * V, 3 * V) == p.reduction.mean_shape.head(3 * V));
  // The side of the cloth facing the door board (normal towards -z, the board
  // lies behind at z <= 0) sees less sky than the side facing the room.
  double board_side = 0, room_side = 0;
  for (int v = 0; v < V; ++v) {
    const bool front_faces_board = m.normals(v, 2) < 0;
    const double front = p.appearance->mean_transfer[48 * v],
                 back = p.appearance->mean_transfer[48 * (V + v)];
    board_side += front_faces_board ? front : back;
    room_side += front_faces_board ? back : front;
  }
  EXPECT_LT(board_side, 0.9 * room_side);
}

// A box the camera never sees (the paper cloth's rail inside the towel's
// fold) can be collision only: the simulator keeps it, the appearance stage
// gets no points of it, and the props after it keep their own points and colour.
TEST(AppearanceStage, AnUndrawnPropCollidesButHasNoScenePoints) {
  const std::string door_cell = "cell = 0.2 ";
  const std::string props =
      "cell = 0.2\n\n[[obstacle]]\nname = \"rail\"\nmin = [0.15, 1.84, 0.02]\n"
      "max = [0.75, 1.845, 0.025]\ndrawn = false\nalbedo = [1, 0, 0]\n\n"
      "[[obstacle]]\nname = \"hook\"\nmin = [0.4, 1.0, 0.0]\nmax = [0.45, 1.05, 0.05]\n"
      "albedo = [0, 1, 0]\n#";
  const auto scene = precompute::load_scene_file(
      testing::edited_tiny_scene(scratch_dir("appearance_undrawn_prop"), door_cell, props));
  ASSERT_EQ(scene.model.obstacles.size(), 3u);
  EXPECT_EQ(scene.model.obstacles[1].name, "rail");
  EXPECT_FALSE(scene.props.at(1).drawn);
  EXPECT_TRUE(scene.props.at(2).drawn);
  const int V = scene.model.vertices();
  const auto m = precompute::scene_mesh(scene);
  ASSERT_EQ(m.points(), 2 * V + kDoorPoints + 24);  // the hook: one quad a face, four points each
  EXPECT_EQ(precompute::scene_point_embedding(scene).weights.rows(), m.points());
  const MatrixXfR rho = precompute::scene_point_albedo(scene);
  ASSERT_EQ(rho.rows(), m.points());
  EXPECT_TRUE(rho.row(m.points() - 1).isApprox(Eigen::RowVector3f(0.0f, 1.0f, 0.0f)));
  EXPECT_TRUE(rho.row(m.points() - 25).isApprox(Eigen::RowVector3f(0.62f, 0.42f, 0.24f)));  // the door's last
  for (Eigen::Index q = 2 * V + kDoorPoints; q < m.points(); ++q) {  // the hook's, not the rail's
    EXPECT_LE(m.rest_positions(q, 1), 1.05f + 1e-6f) << "point " << q;
    EXPECT_GE(m.rest_positions(q, 0), 0.4f - 1e-6f) << "point " << q;
  }

  const auto bad = testing::edited_tiny_scene(scratch_dir("appearance_undrawn_prop_bad"), door_cell,
                                              "cell = 0.2\ndrawn = 0\n#");
  try {
    precompute::load_scene_file(bad);
    ADD_FAILURE() << "drawn = 0 was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("'obstacle[0].drawn'"), std::string::npos) << e.what();
  }
}

TEST(AppearanceStage, SameSeedGivesTheSameAppearanceAndNoAppearanceSkipsIt) {
  const auto pkg = run_tiny("appearance_determinism");
  const auto dir = scratch_dir("appearance_determinism_reduce");
  const auto again = (dir / "again.h5").string(), none = (dir / "none.h5").string();
  const auto orbits = pkg + ".work/orbits.h5";
  const auto r =
      run_tool("phasecast-precompute", args({"reduce", tiny_scene_path().string(), orbits, "-o", again}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto a = core::read_package(pkg), b = core::read_package(again);
  ASSERT_TRUE(a.appearance && b.appearance);
  EXPECT_TRUE(a.appearance->mean_transfer == b.appearance->mean_transfer);
  EXPECT_TRUE(a.appearance->U_a == b.appearance->U_a);
  EXPECT_TRUE(a.appearance->singular_values == b.appearance->singular_values);
  EXPECT_EQ(a.appearance->cluster_nodes, b.appearance->cluster_nodes);
  EXPECT_TRUE(a.appearance->nrbf_weights == b.appearance->nrbf_weights);
  EXPECT_TRUE(a.appearance->nrbf_widths == b.appearance->nrbf_widths);
  EXPECT_TRUE(a.portrait.q_a == b.portrait.q_a);

  const auto skipped =
      run_tool("phasecast-precompute",
               args({"reduce", tiny_scene_path().string(), orbits, "-o", none}, {"--no-appearance"}));
  ASSERT_EQ(skipped.exit_code, 0) << skipped.err;
  const auto c = core::read_package(none);
  EXPECT_FALSE(c.appearance.has_value());
  EXPECT_EQ(c.rank_a(), 0);
  EXPECT_TRUE(c.reduction.U_u == a.reduction.U_u);
}

// The scene's [appearance] rays sets the sphere set when --rays is not given,
// and --rays overrides it: the scene's 32 reproduces --rays 32 bit for bit,
// and differs from the 64 rays the run used.
TEST(AppearanceStage, TheScenesRaysAreTheDefaultAndTheCommandLineOverridesThem) {
  const auto pkg = run_tiny("appearance_rays");  // --rays 64
  const auto dir = scratch_dir("appearance_rays_reduce");
  std::ifstream in(tiny_scene_path());
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = text.find("[appearance]\n");
  ASSERT_NE(at, std::string::npos);
  text.insert(at + 13, "rays = 32\n");
  const auto scene = (dir / "rays32.toml").string();
  std::ofstream(scene) << text;
  std::vector<std::string> reduce = kReduce;
  reduce.erase(std::find(reduce.begin(), reduce.end(), "--rays"),
               std::find(reduce.begin(), reduce.end(), "--rays") + 2);
  const auto orbits = pkg + ".work/orbits.h5";
  const auto from_scene = (dir / "scene.h5").string(), from_flag = (dir / "flag.h5").string();
  std::vector<std::string> a = {"reduce", scene, orbits, "-o", from_scene},
                           b = {"reduce", tiny_scene_path().string(), orbits, "-o", from_flag, "--rays",
                                "32"};
  a.insert(a.end(), reduce.begin(), reduce.end());
  b.insert(b.end(), reduce.begin(), reduce.end());
  for (const auto& command : {a, b}) {
    const auto r = run_tool("phasecast-precompute", command);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const auto s = core::read_package(from_scene), f = core::read_package(from_flag),
             r64 = core::read_package(pkg);
  ASSERT_TRUE(s.appearance && f.appearance && r64.appearance);
  EXPECT_TRUE(s.appearance->mean_transfer == f.appearance->mean_transfer);
  EXPECT_FALSE(s.appearance->mean_transfer == r64.appearance->mean_transfer);
  // Each package records the rays and bounces its transfers were taken with.
  EXPECT_EQ(s.appearance->transfer_rays, 32);
  EXPECT_EQ(f.appearance->transfer_rays, 32);
  EXPECT_EQ(r64.appearance->transfer_rays, 64);
  EXPECT_EQ(s.appearance->transfer_bounces, 1);
  // And the flag wins over the scene's value.
  const auto back64 = (dir / "back64.h5").string();
  std::vector<std::string> c = {"reduce", scene, orbits, "-o", back64};
  c.insert(c.end(), kReduce.begin(), kReduce.end());  // --rays 64
  ASSERT_EQ(run_tool("phasecast-precompute", c).exit_code, 0);
  EXPECT_TRUE(core::read_package(back64).appearance->mean_transfer == r64.appearance->mean_transfer);
}

struct BadOption {
  std::vector<std::string> args;
  std::string message;
};

TEST(AppearanceStage, BadOptionsAreOneLineErrorsBeforeSampling) {
  const auto dir = scratch_dir("appearance_bad");
  const auto pkg = (dir / "bad.h5").string();
  const std::vector<BadOption> cases = {
      {{"--clusters", "0"}, "appearance: expected --clusters >= 1, got 0"},
      {{"--rays", "0"}, "appearance: expected --rays in 1..1048576, got 0"},
      {{"--bounces", "-1"}, "appearance: expected --bounces >= 0, got -1"},
      {{"--eps-a", "1.5"}, "appearance: expected --eps-a in (0, 1), got 1.5"},
      {{"--rank-a", "-2"}, "appearance: expected --rank-a >= 0 (0: use --eps-a), got -2"},
      {{"--held-out", "-1"}, "appearance: expected --held-out >= 0, got -1"},
      {{"--held-out-target", "1.5"}, "appearance: expected --held-out-target in (0, 1), got 1.5"},
      {{"--held-out-target", "nan"}, "appearance: expected --held-out-target in (0, 1), got nan"},
      {{"--held-out-target", "0.1", "--rank-a", "3"},
       "appearance: --held-out-target and --rank-a both fix r_a: give one of them"},
      {{"--held-out-target", "0.1", "--held-out", "1"},
       "appearance: --held-out-target is measured at the picking half of the held-out nodes: expected "
       "--held-out >= 2, got 1"},
      {{"--interpolant", "spline"},
       "--interpolant 'spline': expected best, nrbf, knn, affine-knn or affine-knn-slope"},
      {{"--transfer-weighting", "density"},
       "--transfer-weighting 'density': expected best, equal or cluster-size"},
      {{"--save-transfers", "/nonexistent-phasecast/t.h5"},
       "appearance: --save-transfers '/nonexistent-phasecast/t.h5': expected a file in an existing folder "
       "(/nonexistent-phasecast is not one)"},
      {{"--save-transfers", dir.string()},
       fmt::format("appearance: --save-transfers '{}': expected a file, not a folder", dir.string())},
      {{"--save-transfers", pkg},
       fmt::format("appearance: --save-transfers '{}': expected a file other than the orbit store and the "
                   "package ({})",
                   pkg, pkg)},
      {{"--save-transfers", (dir / "t.h5").string(), "--no-appearance"},
       "appearance: --save-transfers saves the appearance stage's transfers: drop --no-appearance"},
  };
  for (const auto& c : cases) {
    const auto r =
        run_tool("phasecast-precompute", args({"run", tiny_scene_path().string(), "-o", pkg}, c.args));
    EXPECT_NE(r.exit_code, 0) << c.message;
    EXPECT_TRUE(one_line(r.err)) << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(pkg + ".work")) << c.message;  // failed before sampling
  }
}

TEST(AppearanceStage, MoreClustersThanStateNodesIsAOneLineError) {
  const auto pkg = run_tiny("appearance_clusters_ok");  // leaves the orbits
  const auto out = (scratch_dir("appearance_too_many") / "x.h5").string();
  const auto r = run_tool("phasecast-precompute",
                          args({"reduce", tiny_scene_path().string(), pkg + ".work/orbits.h5", "-o", out},
                               {"--clusters", "100000"}));
  EXPECT_NE(r.exit_code, 0);
  const auto n = core::read_package(pkg).portrait.nodes();
  EXPECT_EQ(
      last_line(r.err),
      fmt::format("phasecast-precompute: appearance: expected --clusters in 1..{} (the state nodes of the "
                  "package), got 100000",
                  n))
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
}

// A render mesh is lit where its embedding puts it: under a rigid motion of
// the simulated cloth, the subdivided cloth (both sides) moves rigidly with
// it and the door stays, so its transfer is taken on the moved render mesh.
TEST(AppearanceStage, RenderMeshPointsAreDeformedByTheirEmbedding) {
  const auto scene = precompute::load_scene_file(
      testing::edited_tiny_scene(scratch_dir("appearance_render_mesh"), "grid = { origin",
                                 "render = { subdivide = 1 }\ngrid = { origin"));
  const auto m = precompute::scene_mesh(scene);
  const auto W = precompute::scene_point_embedding(scene);
  // In double, per coordinate: fixed-size float temporaries trip GCC 12's -Warray-bounds.
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1, 0.3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.05, -0.1, 0.2);
  const auto moved_rigidly = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return R * x + t; };
  const int V = scene.model.vertices();
  Eigen::RowVectorXf frame(3 * V);
  for (int v = 0; v < V; ++v) {
    const Eigen::Vector3d y = moved_rigidly(scene.model.rest.segment<3>(3 * v));
    for (int k = 0; k < 3; ++k) frame(3 * v + k) = static_cast<float>(y[k]);
  }
  const MatrixXfR x = precompute::deformed_scene_points(m, W, frame);
  int moved = 0;
  for (Eigen::Index p = 0; p < m.points(); ++p) {
    const Eigen::Vector3d rest = m.rest_positions.row(p).cast<double>().transpose();
    const bool deformable = m.deformable[static_cast<size_t>(p)];
    const Eigen::Vector3d expected = deformable ? moved_rigidly(rest) : rest;
    double off = 0;
    for (int k = 0; k < 3; ++k) off = std::max(off, std::abs(x(p, k) - expected[k]));
    EXPECT_LT(off, 1e-5) << "point " << p;
    moved += deformable;
  }
  EXPECT_GT(moved, 2 * V);  // the render mesh, not the simulated vertices
  precompute::TransferOptions options;
  options.rays = 16;
  EXPECT_EQ(precompute::transfer_at_frame(m, W, frame, options).rows(), m.points());
}

}  // namespace
}  // namespace phasecast
