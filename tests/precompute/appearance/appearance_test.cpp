// The whole appearance model (§4) on the synthetic plate package: k-means on
// q_u, shadowed transfer of each representative's deformed mesh, transfer
// SVD and NRBF, written into a package that validates and reads back.

#include "phasecast/core/dense_svd.h"
#include "phasecast/core/mesh_geometry.h"
#include "phasecast/core/package_summary.h"
#include "phasecast/precompute/appearance/appearance_stage.h"
#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/appearance/transfer_appearance.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <random>

namespace phasecast {
namespace {

using namespace precompute;

MatrixXfR transfer_fields(const core::ScenePackage& p, const std::vector<std::int32_t>& nodes) {
  const int S = p.mesh.points();
  MatrixXfR fields(static_cast<Eigen::Index>(nodes.size()), 48 * S);
  TransferOptions o;
  o.mode = TransferMode::shadowed;
  o.rays = 128;
  for (size_t j = 0; j < nodes.size(); ++j) {
    const Eigen::VectorXf x =
        p.reduction.mean_shape + p.reduction.U_u * p.portrait.q_u.row(nodes[j]).transpose();
    const MatrixXfR positions = Eigen::Map<const MatrixXfR>(x.data(), S, 3);
    const MatrixXfR T =
        compute_transfer(positions, p.mesh.triangles, core::vertex_normals(positions, p.mesh.triangles), o);
    fields.row(static_cast<Eigen::Index>(j)) = Eigen::Map<const Eigen::RowVectorXf>(T.data(), 48 * S);
  }
  return fields;
}

MatrixXfR transfer_fields(const core::ScenePackage& p, const KMeansResult& clusters) {
  return transfer_fields(p, clusters.representatives);
}

// The plate in 6 clusters, with the true transfer at `held_out` other nodes.
struct PlateWithTruth {
  core::ScenePackage package;
  KMeansResult clusters;
  HeldOutTruth truth;
};

PlateWithTruth plate_with_held_out(int held_out) {
  PlateWithTruth t{testing::make_plate_package({.grid = 6, .appearance = false}), {}, {}};
  t.clusters = kmeans(t.package.portrait.q_u, {.clusters = 6, .seed = 3});
  t.truth.nodes = draw_held_out_nodes(t.package.portrait.nodes(), t.clusters.representatives, held_out, 5);
  t.truth.fields = transfer_fields(t.package, t.truth.nodes);
  return t;
}

TEST(Appearance, FillsAValidPackage) {
  core::ScenePackage p = testing::make_plate_package({.grid = 6, .appearance = false});
  const auto clusters = kmeans(p.portrait.q_u, {.clusters = 8, .seed = 3});
  const MatrixXfR fields = transfer_fields(p, clusters);
  const auto model = fit_appearance_model(p.portrait.q_u, clusters, fields, {.reduction = {.eps_a = 1e-3}});
  const auto& a = model.appearance;
  ASSERT_GE(a.rank(), 1);
  EXPECT_EQ(a.clusters(), 8);
  EXPECT_EQ(a.cluster_nodes, clusters.representatives);
  EXPECT_EQ(model.q_a.rows(), p.portrait.nodes());
  EXPECT_EQ(model.q_a.cols(), a.rank());
  ASSERT_EQ(model.candidates.size(), 4u);  // nrbf, knn and affine-knn by both metrics, tuned by leave-one-out
  for (const auto& c : model.candidates) EXPECT_TRUE(std::isfinite(c.interpolant.leave_one_out));
  EXPECT_FALSE(a.held_out);  // no held-out truth given
  // At a cluster node the k-nearest-neighbour interpolant returns that node's own q_a^j.
  const auto r = reduce_transfer(fields, {.eps_a = 1e-3});
  const auto knn =
      fit_appearance_model(p.portrait.q_u, clusters, fields,
                           {.reduction = {.eps_a = 1e-3}, .interpolant = InterpolantChoice::knn});
  EXPECT_EQ(knn.appearance.interpolant, "knn");
  for (int j = 0; j < 8; ++j) {
    const Eigen::VectorXf got = knn.q_a.row(a.cluster_nodes[static_cast<size_t>(j)]).transpose();
    EXPECT_LT((got - r.Q_a.col(j)).norm(), 1e-5f * r.Q_a.norm()) << "cluster " << j;
  }
  p.appearance = a;
  p.portrait.q_a = model.q_a;
  p.attributes.eps_a = 1e-3;
  const auto path = testing::scratch_dir("appearance_package") / "plate.h5";
  core::write_package(p, path);  // validates
  const auto back = core::read_package(path);
  ASSERT_TRUE(back.appearance.has_value());
  EXPECT_EQ(back.appearance->U_a, a.U_a);
  EXPECT_EQ(back.appearance->nrbf_weights, a.nrbf_weights);
  EXPECT_EQ(back.portrait.q_a, model.q_a);
}

// A second reader of the stored affine-knn: q_a rebuilt by hand from what
// the package holds (k, the (1 + r_u) x r_a map row by row, the remainders
// as weights) is the q_a it serves.
// Both metrics: the stored map and remainders, with neighbours found in q_u
// or in the map's image, give back the served q_a at every node.
class AffineKnnPackage : public ::testing::TestWithParam<InterpolantChoice> {};

TEST_P(AffineKnnPackage, IsStoredSoThatItsQaCanBeRebuilt) {
  const bool slope = GetParam() == InterpolantChoice::affine_knn_slope;
  core::ScenePackage p = testing::make_plate_package({.grid = 6, .appearance = false});
  const auto clusters = kmeans(p.portrait.q_u, {.clusters = 8, .seed = 3});
  const auto model = fit_appearance_model(p.portrait.q_u, clusters, transfer_fields(p, clusters),
                                          {.reduction = {.eps_a = 1e-3}, .interpolant = GetParam()});
  ASSERT_GE(model.appearance.rank(), 1);
  p.appearance = model.appearance;
  p.portrait.q_a = model.q_a;
  p.attributes.eps_a = 1e-3;
  const auto path =
      testing::scratch_dir(slope ? "appearance_affine_knn_slope" : "appearance_affine_knn") / "plate.h5";
  core::write_package(p, path);  // validates
  const auto back = core::read_package(path);
  const auto& a = *back.appearance;
  ASSERT_EQ(a.interpolant, slope ? "affine-knn-slope" : "affine-knn");
  EXPECT_EQ(core::summarize(back, path).interpolant,
            fmt::format("{} (k = {}, ridge {:g})", a.interpolant, a.interpolant_parameters[0],
                        a.nrbf_regularization));
  const Eigen::Index r_u = a.nrbf_centers.cols(), r_a = a.U_a.cols();
  ASSERT_EQ(a.interpolant_parameters.size(), 1 + (1 + r_u) * r_a);
  const int k = static_cast<int>(a.interpolant_parameters[0]);
  Eigen::MatrixXd map(1 + r_u, r_a);
  for (Eigen::Index i = 0; i < map.rows(); ++i)
    for (Eigen::Index j = 0; j < r_a; ++j) map(i, j) = a.interpolant_parameters[1 + i * r_a + j];
  const Eigen::MatrixXd B = map.bottomRows(r_u);
  const double eps = B.squaredNorm() > 0 ? 1e-6 * B.squaredNorm() / static_cast<double>(r_u) : 1.0;
  // The largest gap between the served q_a and the one rebuilt with neighbours in the map's image
  // (in_image) or in q_u.
  const auto rebuilt_gap = [&](bool in_image) {
    const auto distance2 = [&](const Eigen::VectorXd& dx) {
      return in_image ? (dx.transpose() * B).squaredNorm() + eps * dx.squaredNorm() : dx.squaredNorm();
    };
    double worst = 0;
    for (Eigen::Index n = 0; n < back.portrait.nodes(); ++n) {
      const Eigen::VectorXd q = back.portrait.q_u.row(n).transpose().cast<double>();
      std::vector<std::pair<double, Eigen::Index>> d;
      for (Eigen::Index c = 0; c < a.nrbf_centers.rows(); ++c)
        d.emplace_back(distance2(a.nrbf_centers.row(c).transpose().cast<double>() - q), c);
      std::sort(d.begin(), d.end());
      Eigen::RowVectorXd rest = Eigen::RowVectorXd::Zero(r_a);
      if (d[0].first == 0) {
        rest = a.nrbf_weights.row(d[0].second).cast<double>();
      } else {
        double total = 0;
        for (int i = 0; i < k; ++i) {
          rest += a.nrbf_weights.row(d[static_cast<size_t>(i)].second).cast<double>() /
                  d[static_cast<size_t>(i)].first;
          total += 1 / d[static_cast<size_t>(i)].first;
        }
        rest /= total;
      }
      const Eigen::RowVectorXd want = map.row(0) + q.transpose() * map.bottomRows(r_u) + rest;
      worst = std::max(worst, (want - back.portrait.q_a.row(n).cast<double>()).norm());
    }
    return worst;
  };
  const double worst = rebuilt_gap(slope);
  // Not vacuous: the other metric rebuilds another q_a on this package.
  EXPECT_GT(rebuilt_gap(!slope), 1e-3 * back.portrait.q_a.cast<double>().norm());
  EXPECT_LT(worst, 1e-5 * back.portrait.q_a.cast<double>().norm());
  // At its own node each cluster gets its projection back: map plus remainder is the sample.
  const auto r = reduce_transfer(transfer_fields(p, clusters), {.eps_a = 1e-3});
  for (int j = 0; j < 8; ++j) {
    const Eigen::VectorXf got = back.portrait.q_a.row(a.cluster_nodes[static_cast<size_t>(j)]).transpose();
    EXPECT_LT((got - r.Q_a.col(j)).norm(), 1e-5f * r.Q_a.norm()) << "cluster " << j;
  }
}

INSTANTIATE_TEST_SUITE_P(BothMetrics, AffineKnnPackage,
                         ::testing::Values(InterpolantChoice::affine_knn,
                                           InterpolantChoice::affine_knn_slope));

TEST(Appearance, OneClusterHasRankZero) {
  core::ScenePackage p = testing::make_plate_package({.grid = 4, .appearance = false});
  const auto clusters = kmeans(p.portrait.q_u, {.clusters = 1});
  const auto model = fit_appearance_model(p.portrait.q_u, clusters, transfer_fields(p, clusters), {});
  EXPECT_EQ(model.appearance.rank(), 0);
  EXPECT_EQ(model.q_a.rows(), p.portrait.nodes());
  EXPECT_EQ(model.q_a.cols(), 0);
  EXPECT_FALSE(model.appearance.held_out);
  p.appearance = model.appearance;
  p.portrait.q_a = model.q_a;
  EXPECT_NO_THROW(core::validate_package(p, "one cluster"));
}

// The held-out figure is what a client would show: M-bar + U_a q_a at the
// node, read back from the package, against the true transfer there.
TEST(Appearance, HeldOutErrorIsTheServedTransferAgainstTheTruth) {
  const auto [p, clusters, truth] = plate_with_held_out(12);
  ASSERT_EQ(truth.nodes.size(), 12u);
  for (auto n : truth.nodes)
    EXPECT_EQ(std::count(clusters.representatives.begin(), clusters.representatives.end(), n), 0);
  // Equal weights, so that the clusters' own figure is the paper's sigma ratio
  // (the choice of weighting is tested below).
  const auto model =
      fit_appearance_model(p.portrait.q_u, clusters, transfer_fields(p, clusters),
                           {.reduction = {.rank = 3}, .weighting = WeightingChoice::equal}, truth);
  const auto& a = model.appearance;
  ASSERT_TRUE(a.held_out && a.held_out->l2_floor_of_variation);  // every figure measured
  EXPECT_EQ(a.transfer_weighting, "equal");
  ASSERT_EQ(a.held_out->nodes.size(), 6u);  // the second half: the first picked the interpolant
  EXPECT_TRUE(std::equal(a.held_out->nodes.begin(), a.held_out->nodes.end(), truth.nodes.begin() + 6));
  // A second reader: plain sums over the served fields.
  double err2 = 0, centred2 = 0, truth2 = 0;
  Eigen::MatrixXd E(a.mean_transfer.size(), 6), D(a.mean_transfer.size(), 6);  // columns: nodes
  for (size_t i = 0; i < 6; ++i) {
    const auto node = a.held_out->nodes[i];
    const Eigen::VectorXd served = (a.mean_transfer + a.U_a * model.q_a.row(node).transpose()).cast<double>();
    const Eigen::VectorXd m = truth.fields.row(static_cast<Eigen::Index>(6 + i)).transpose().cast<double>();
    E.col(static_cast<Eigen::Index>(i)) = m - served;
    D.col(static_cast<Eigen::Index>(i)) = m - a.mean_transfer.cast<double>();
    err2 += (m - served).squaredNorm();
    centred2 += (m - a.mean_transfer.cast<double>()).squaredNorm();
    truth2 += m.squaredNorm();
  }
  EXPECT_NEAR(a.held_out->total, std::sqrt(err2 / centred2), 1e-4);
  // The paper's relErr: the relative l2 (spectral) norm, by a full SVD here.
  const auto l2 = [](const Eigen::MatrixXd& X) { return core::spectral_norm(X); };
  EXPECT_NEAR(*a.held_out->l2_total, l2(E) / l2(D), 1e-4);
  EXPECT_LE(*a.held_out->l2_truncation, *a.held_out->l2_total + 1e-6);  // the truncation is part of the error
  // As many reported nodes (6) as clusters: the clusters' own figure is the paper's sigma_4 / sigma_1.
  EXPECT_NEAR(*a.held_out->clusters_l2_truncation, a.singular_values[3] / a.singular_values[0], 1e-5);
  // The floor: sigma_4 / sigma_1 of the centred truth itself, which the
  // clusters' basis can approach but not beat.
  const Eigen::VectorXd sigma_d = core::singular_values(D);
  EXPECT_NEAR(*a.held_out->l2_floor, sigma_d[3] / sigma_d[0], 1e-4);
  EXPECT_GT(*a.held_out->l2_floor, 1e-3);  // six nodes, rank 3: not vacuous
  EXPECT_LE(*a.held_out->l2_floor, *a.held_out->l2_truncation + 1e-6);
  // Fig. 12 out of sample: at r_a, the truncation above; with all N_a - 1 = 5
  // directions in, what the cluster fields' span leaves (the 5 leading left
  // singular vectors of their centred matrix, by a dense SVD here; the sixth
  // is round-off of the float M-bar).
  ASSERT_EQ(a.held_out->truncation_curve.size(), 5);
  EXPECT_NEAR(a.held_out->truncation_curve[2], *a.held_out->l2_truncation, 1e-4);
  const Eigen::MatrixXd F =
      (transfer_fields(p, clusters).rowwise() - a.mean_transfer.transpose()).transpose().cast<double>();
  const Eigen::MatrixXd Q = core::dense_svd(F, core::SvdVectors::left).U.leftCols(5);
  const double span = l2(D - Q * (Q.transpose() * D)) / l2(D);
  EXPECT_NEAR(a.held_out->truncation_curve[4], span, 1e-4);
  EXPECT_GT(span, 1e-3) << "not vacuous: the held-out fields leave the clusters' span";
  EXPECT_LT(span, *a.held_out->l2_truncation) << "more directions leave less";
  EXPECT_NEAR(a.held_out->of_transfer, std::sqrt(err2 / truth2), 1e-5);
  // Of the nodes' own variation: M less their own mean, which no model moves.
  const Eigen::MatrixXd V = D.colwise() - D.rowwise().mean();
  EXPECT_NEAR(*a.held_out->of_variation, E.norm() / V.norm(), 1e-4);
  EXPECT_NEAR(*a.held_out->l2_of_variation, l2(E) / l2(V), 1e-4);
  const Eigen::VectorXd sigma_v = core::singular_values(V);
  EXPECT_NEAR(*a.held_out->l2_floor_of_variation, sigma_v[3] / sigma_v[0], 1e-4);
  EXPECT_GT(*a.held_out->l2_floor_of_variation, 1e-3);  // five independent columns, rank 3: not vacuous
  EXPECT_LE(*a.held_out->l2_floor_of_variation,
            *a.held_out->l2_of_variation + 1e-6);                         // |E|_2 >= |E J|_2 >= sigma_4(M J)
  EXPECT_GE(*a.held_out->l2_of_variation, *a.held_out->l2_total - 1e-6);  // |D J|_2 <= |D|_2
  EXPECT_GT(a.held_out->total, 1e-3);  // not vacuous: these nodes are not samples
  EXPECT_NEAR(
      a.held_out->total * a.held_out->total,
      a.held_out->truncation * a.held_out->truncation + a.held_out->interpolation * a.held_out->interpolation,
      1e-5);
  // The kept interpolant is the one the picking half preferred.
  ASSERT_EQ(model.candidates.size(), 4u);
  for (size_t i = 1; i < 4; ++i)
    EXPECT_LE(model.candidates[0].selection.of_transfer, model.candidates[i].selection.of_transfer);
  EXPECT_EQ(a.interpolant, interpolant_name(model.candidates[0].interpolant.kind));
  // The basis comparison measures the served basis at the reported half: its
  // truncation there, against a basis of the picking half's six fields.
  ASSERT_TRUE(model.basis_comparison.has_value());
  EXPECT_EQ(model.basis_comparison->drawn_fields, 6);
  EXPECT_NEAR(model.basis_comparison->served.total, a.held_out->truncation, 1e-5);
  const Eigen::MatrixXd T = D - a.U_a.cast<double>() * (a.U_a.cast<double>().transpose() * D);
  EXPECT_NEAR(model.basis_comparison->served.of_variation, T.norm() / V.norm(), 1e-4);
  // Written and read back, the figures survive.
  core::ScenePackage out = p;
  out.appearance = a;
  out.portrait.q_a = model.q_a;
  const auto path = testing::scratch_dir("appearance_held_out") / "plate.h5";
  core::write_package(out, path);
  const auto back = core::read_package(path);
  ASSERT_TRUE(back.appearance->held_out);
  const core::HeldOutFigures& h = *back.appearance->held_out;
  EXPECT_EQ(h.nodes, a.held_out->nodes);
  EXPECT_EQ(h.total, a.held_out->total);
  EXPECT_EQ(h.of_transfer, a.held_out->of_transfer);
  EXPECT_EQ(h.l2_floor, a.held_out->l2_floor);
  EXPECT_EQ(h.l2_floor_of_variation, a.held_out->l2_floor_of_variation);
  ASSERT_TRUE(h.l2_of_variation_spread);
  EXPECT_EQ(h.l2_of_variation_spread->p90, a.held_out->l2_of_variation_spread->p90);
  EXPECT_EQ(h.truncation_curve, a.held_out->truncation_curve);
  EXPECT_EQ(back.appearance->interpolant, a.interpolant);
  EXPECT_EQ(back.appearance->transfer_weighting, "equal");
}

// Fields of a 2-D state that a rank-2 basis cannot hold exactly: 48 smooth
// features of q, 4 points' worth.
MatrixXfR feature_fields(const MatrixXfR& q, const std::vector<std::int32_t>& nodes) {
  MatrixXfR fields(static_cast<Eigen::Index>(nodes.size()), 48 * 4);
  for (size_t i = 0; i < nodes.size(); ++i) {
    const double x = q(nodes[i], 0), y = q(nodes[i], 1);
    for (int k = 0; k < 48 * 4; ++k)
      fields(static_cast<Eigen::Index>(i), k) =
          static_cast<float>(std::sin(0.3 * (k % 7 + 1) * x + 0.2 * (k % 5) * y + 0.1 * k));
  }
  return fields;
}

// Most states crowd near the rest, a few lie far out, and k-means gives the
// few as many clusters as the many.
MatrixXfR crowd_and_outliers() {
  std::mt19937_64 rng(21);
  const auto uniform = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  MatrixXfR q_u(400, 2);
  for (Eigen::Index n = 0; n < 400; ++n) {
    const double radius = n < 360 ? 0.3 * uniform() : 3 + 2 * uniform(), angle = 2 * M_PI * uniform();
    q_u.row(n) << static_cast<float>(radius * std::cos(angle)), static_cast<float>(radius * std::sin(angle));
  }
  return q_u;
}

// With equal weights M-bar and U_a follow the outliers, weighted by cluster
// size they follow the states. Held-out nodes are drawn from the states, so
// the picking half prefers the weighted model, and the reported half (which
// never chose) confirms it.
TEST(Appearance, WeightingByClusterSizeIsKeptWhenItServesTheStatesBetter) {
  const MatrixXfR q_u = crowd_and_outliers();
  const auto clusters = kmeans(q_u, {.clusters = 12, .seed = 2});
  const Eigen::VectorXd weights = cluster_size_weights(clusters);
  EXPECT_NEAR(weights.mean(), 1.0, 1e-12);
  EXPECT_GT(weights.maxCoeff(), 4 * weights.minCoeff()) << "not vacuous: clusters of unequal size";
  HeldOutTruth truth;
  truth.nodes = draw_held_out_nodes(400, clusters.representatives, 60, 4);
  truth.fields = feature_fields(q_u, truth.nodes);
  const MatrixXfR fields = feature_fields(q_u, clusters.representatives);
  const AppearanceOptions best{.reduction = {.rank = 2}};
  const auto model = fit_appearance_model(q_u, clusters, fields, best, truth);
  ASSERT_EQ(model.candidates.size(), 8u);  // both weightings, four interpolants
  for (size_t i = 1; i < 8; ++i)
    EXPECT_LE(model.candidates[0].selection.of_transfer, model.candidates[i].selection.of_transfer);
  EXPECT_EQ(model.candidates[0].weighting, TransferWeighting::cluster_size);
  EXPECT_EQ(model.appearance.transfer_weighting, "cluster size");
  // Kept because its gain over the best equal candidate is beyond the noise
  // of the 30 picking nodes, as the paired comparison of their errors says.
  ASSERT_TRUE(model.weighting_gain);
  EXPECT_TRUE(model.weighting_gain->beyond_noise())
      << model.weighting_gain->gain << " vs noise " << model.weighting_gain->noise;
  const auto best_equal = std::find_if(model.candidates.begin(), model.candidates.end(),
                                       [](const auto& c) { return c.weighting == TransferWeighting::equal; });
  ASSERT_NE(best_equal, model.candidates.end());
  const PairedGain recomputed =
      paired_gain(best_equal->selection.node_error2, model.candidates[0].selection.node_error2);
  EXPECT_DOUBLE_EQ(model.weighting_gain->gain, recomputed.gain);
  EXPECT_NEAR(model.candidates[0].selection.node_error2.sum() / best_equal->selection.node_error2.sum(),
              1 - recomputed.gain, 1e-12);
  // M-bar is the cluster-size mean of the fields.
  const Eigen::VectorXf mean = (fields.transpose().cast<double>() * weights / weights.sum()).cast<float>();
  EXPECT_LT((model.appearance.mean_transfer - mean).norm(), 1e-5f * mean.norm());
  // On the reported half, against the nodes' own variation (which no model moves).
  const auto equal = fit_appearance_model(
      q_u, clusters, fields, {.reduction = {.rank = 2}, .weighting = WeightingChoice::equal}, truth);
  EXPECT_EQ(equal.appearance.transfer_weighting, "equal");
  const float weighted_error = *model.appearance.held_out->of_variation,
              equal_error = *equal.appearance.held_out->of_variation;
  EXPECT_LT(weighted_error, 0.9f * equal_error) << weighted_error << " vs " << equal_error;
  // Without held-out truth nothing compares the two: equal weights, as the paper.
  const auto unjudged = fit_appearance_model(q_u, clusters, fields, best);
  ASSERT_EQ(unjudged.candidates.size(), 4u);
  EXPECT_EQ(unjudged.appearance.transfer_weighting, "equal");
  // Asked for, cluster sizes are used without held-out truth too.
  const auto asked = fit_appearance_model(
      q_u, clusters, fields, {.reduction = {.rank = 2}, .weighting = WeightingChoice::cluster_size});
  EXPECT_EQ(asked.appearance.transfer_weighting, "cluster size");
  EXPECT_LT((asked.appearance.mean_transfer - mean).norm(), 1e-5f * mean.norm());
  // r_a is what eps_a gives the paper's A_a, whichever weighting is kept (so
  // the two compare at one client cost): at an eps_a between the two spectra
  // the weighted fields alone would count another rank.
  const auto plain = reduce_transfer(fields, {.eps_a = 0, .rank = 1});
  const auto heavy = reduce_transfer(fields, {.eps_a = 0, .rank = 1}, weights);
  double eps = -1;
  for (Eigen::Index i = 1; i < 8 && eps < 0; ++i) {
    const double e = plain.singular_values[i] / plain.singular_values[0];
    const double w = heavy.singular_values[i] / heavy.singular_values[0];
    if (std::abs(e - w) > 0.02 * e) eps = (e + w) / 2;
  }
  ASSERT_GT(eps, 0) << "the spectra differ";
  const int rank = reduce_transfer(fields, {.eps_a = eps}).rank();
  ASSERT_NE(reduce_transfer(fields, {.eps_a = eps}, weights).rank(), rank) << "not vacuous";
  const auto by_eps = fit_appearance_model(
      q_u, clusters, fields, {.reduction = {.eps_a = eps}, .weighting = WeightingChoice::cluster_size});
  EXPECT_EQ(by_eps.appearance.transfer_weighting, "cluster size");
  EXPECT_EQ(by_eps.appearance.rank(), rank);
  // The package's spectrum stays the paper's A_a's.
  EXPECT_EQ(by_eps.appearance.singular_values, plain.singular_values);
}

// Two held-out nodes: one picks, one is reported. A single node does not
// vary about its own mean, so the figures of that variation are not stored
// (they would read 0), and the first 8 are.
TEST(Appearance, OneReportedNodeKeepsTheFirstEightFigures) {
  const auto [p, clusters, truth] = plate_with_held_out(2);
  const auto model = fit_appearance_model(p.portrait.q_u, clusters, transfer_fields(p, clusters),
                                          {.reduction = {.rank = 3}}, truth);
  const auto& a = model.appearance;
  ASSERT_EQ(a.held_out->nodes.size(), 1u);
  EXPECT_TRUE(a.held_out->l2_floor);  // the first eight figures
  EXPECT_FALSE(a.held_out->of_variation || a.held_out->l2_of_variation || a.held_out->l2_floor_of_variation);
  EXPECT_GT(a.held_out->total, 1e-3);  // the served error itself is still measured
  EXPECT_FALSE(a.held_out->l2_total_spread || a.held_out->l2_truncation_spread);
  EXPECT_EQ(a.held_out->truncation_curve.size(), 5);  // one node still has a curve
  core::ScenePackage out = p;
  out.appearance = a;
  out.portrait.q_a = model.q_a;
  EXPECT_NO_THROW(core::validate_package(out, "one reported node"));
}

// held_out_target: r_a is the least rank whose truncation at the picking
// half (the first half of the held-out nodes) reaches the target, read here
// from the curve of the paper's equal-weight SVD measured at those nodes.
TEST(Appearance, HeldOutTargetSetsTheLeastRankThatReachesItAtThePickingHalf) {
  const auto [p, clusters, truth] = plate_with_held_out(12);
  const MatrixXfR fields = transfer_fields(p, clusters);
  const VectorXf curve = held_out_truncation_curve(fields, reduce_transfer(fields, {.eps_a = 0, .rank = 1}),
                                                   truth.fields.topRows(6));
  ASSERT_EQ(curve.size(), 5);
  ASSERT_GT(curve[1], curve[2] + 1e-4) << "not vacuous: ranks 2 and 3 differ";
  ASSERT_GT(curve[4], 1e-4) << "not vacuous: the span leaves something";
  const auto options = [](double target) {
    AppearanceOptions o;
    o.reduction.eps_a = 0.5;
    o.weighting = WeightingChoice::equal;
    o.held_out_target = target;
    return o;
  };
  const auto fit = [&](double target) {
    return fit_appearance_model(p.portrait.q_u, clusters, fields, options(target), truth);
  };
  // A target between rank 2's and rank 3's truncation picks rank 3, whatever eps_a says ...
  const auto model = fit(0.5 * (curve[1] + curve[2]));
  ASSERT_TRUE(model.rank_choice.has_value());
  EXPECT_EQ(model.appearance.rank(), 3);
  EXPECT_TRUE(model.rank_choice->reached);
  EXPECT_EQ(model.rank_choice->picking_nodes, 6);
  EXPECT_NEAR(model.rank_choice->truncation, curve[2], 1e-6);
  EXPECT_NE(fit_appearance_model(p.portrait.q_u, clusters, fields, options(0), truth).appearance.rank(), 3)
      << "eps_a alone would give another rank";
  // ... and one below what the span leaves takes every direction, saying so.
  const auto all = fit(0.5 * curve[4]);
  EXPECT_EQ(all.appearance.rank(), 5);
  EXPECT_FALSE(all.rank_choice->reached);
  EXPECT_NEAR(all.rank_choice->truncation, curve[4], 1e-6);
  // Without picking nodes there is nothing to measure it at.
  EXPECT_THROW(fit_appearance_model(p.portrait.q_u, clusters, fields, options(0.1), {}),
               std::invalid_argument);
}

TEST(Appearance, ClusterSizeWeightsRejectAForeignLabel) {
  KMeansResult clusters;
  clusters.representatives = {0, 1};
  clusters.labels = {0, 1, 2};
  try {
    cluster_size_weights(clusters);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "cluster_size_weights: label 2 is not a cluster in 0..1");
  }
}

// A_a with singular values chosen by hand: rows mean + L diag(sigma) R^T,
// L's columns orthonormal and of zero sum (so the rows' mean is `mean`).
MatrixXfR fields_with_spectrum(const std::vector<double>& sigma, Eigen::Index Na, Eigen::Index width) {
  const auto k = static_cast<Eigen::Index>(sigma.size());
  std::srand(7);
  Eigen::MatrixXd L = Eigen::MatrixXd::Random(Na, k);
  L.rowwise() -= L.colwise().mean();
  L = Eigen::HouseholderQR<Eigen::MatrixXd>(L).householderQ() * Eigen::MatrixXd::Identity(Na, k);
  const Eigen::MatrixXd R =
      Eigen::HouseholderQR<Eigen::MatrixXd>(Eigen::MatrixXd::Random(width, k)).householderQ() *
      Eigen::MatrixXd::Identity(width, k);
  const Eigen::RowVectorXd mean = Eigen::RowVectorXd::Random(width);
  const Eigen::VectorXd s = Eigen::Map<const Eigen::VectorXd>(sigma.data(), k);
  return ((L * s.asDiagonal() * R.transpose()).rowwise() + mean).cast<float>();
}

// The paper's relErr (§2.3.1) of the held-out figure: on the clusters
// themselves, served exactly, it must be sigma_{r+1}/sigma_1, which differs
// from the Frobenius ratio the other figures use.
TEST(Appearance, HeldOutErrorInThePapersMetricIsTheSpectralRatio) {
  const std::vector<double> sigma{10, 5, 3, 1, 0.5};
  const MatrixXfR fields = fields_with_spectrum(sigma, 8, 48 * 5);
  const auto r = reduce_transfer(fields, {.rank = 2});
  ASSERT_EQ(r.rank(), 2);
  ASSERT_NEAR(r.singular_values[2] / r.singular_values[0], 0.3, 1e-5);
  HeldOutTruth truth;
  truth.fields = fields;
  for (int j = 0; j < 8; ++j) truth.nodes.push_back(j);
  const MatrixXfR best = r.Q_a.transpose();
  const auto exact = truth_error(r, truth, best);
  EXPECT_NEAR(exact.l2_truncation, 0.3, 1e-4);
  EXPECT_NEAR(exact.l2_total, 0.3, 1e-4);
  EXPECT_NEAR(exact.truncation, std::sqrt((9 + 1 + 0.25) / (100 + 25 + 9 + 1 + 0.25)), 1e-4);
  EXPECT_NEAR(exact.interpolation, 0, 1e-5);
  // The basis is the nodes' own top two directions: it reaches the floor.
  EXPECT_NEAR(exact.l2_floor, 0.3, 1e-4);
  // Serving the mean alone leaves all of M - M-bar: the error is the whole of it.
  const auto mean_only = truth_error(r, truth, MatrixXfR::Zero(8, 2));
  EXPECT_NEAR(mean_only.l2_total, 1, 1e-5);
  EXPECT_NEAR(mean_only.l2_truncation, 0.3, 1e-4);
  EXPECT_NEAR(mean_only.l2_floor, 0.3, 1e-4);  // the truth's and M-bar's, not the served q_a's
}

// The floor at held-out nodes is the least l2 truncation of any rank-r_a
// basis (Eckart-Young): bases from other fields stay above it, the nodes' own
// reaches it, and no more nodes than r_a leave nothing below which to fall.
TEST(Appearance, HeldOutFloorIsTheLeastAnyBasisOfThatRankReaches) {
  const MatrixXfR nodes = fields_with_spectrum({10, 4, 2, 1}, 9, 48 * 4);
  HeldOutTruth truth;
  truth.fields = nodes;
  for (int h = 0; h < 9; ++h) truth.nodes.push_back(100 + h);
  const auto own = reduce_transfer(nodes, {.rank = 2});
  const auto fitted = truth_error(own, truth, own.Q_a.transpose());
  const double floor = fitted.l2_floor;
  EXPECT_NEAR(floor, 0.2, 1e-4);
  // Of the nodes' own variation the floor is their own spectrum, reached by their own model.
  EXPECT_NEAR(fitted.l2_floor_of_variation, 0.2, 1e-4);
  EXPECT_NEAR(fitted.l2_of_variation, 0.2, 1e-4);
  std::mt19937_64 rng(3);
  const auto noise = [&] { return static_cast<float>(static_cast<double>(rng() % 2001) / 1000.0 - 1.0); };
  for (int trial = 0; trial < 6; ++trial) {
    // Other fields: the nodes perturbed and shifted by a common row, so their
    // basis is near the nodes' and their mean is off the nodes' mean.
    MatrixXfR other = nodes;
    Eigen::RowVectorXf shift(nodes.cols());
    for (auto& x : shift) x = 0.25f * noise();
    other.rowwise() += shift;
    for (Eigen::Index i = 0; i < other.size(); ++i) other.data()[i] += 0.05f * noise();
    const auto r = reduce_transfer(other, {.rank = 2});
    const auto e = truth_error(r, truth, MatrixXfR::Zero(9, 2));
    // The floor is the nodes' spectrum about this model's M-bar (a dense SVD
    // here), not about their own mean (0.2): the offset is one more direction.
    const Eigen::MatrixXd D = (nodes.rowwise() - r.mean_transfer.transpose()).transpose().cast<double>();
    const Eigen::VectorXd s = core::singular_values(D);
    EXPECT_NEAR(e.l2_floor, s[2] / s[0], 1e-4) << trial;
    EXPECT_GT(std::abs(e.l2_floor - floor), 0.05) << trial;
    EXPECT_GE(e.l2_truncation, e.l2_floor - 1e-6) << trial;
    // That floor does not move with M-bar, and bounds the model whatever its mean.
    EXPECT_NEAR(e.l2_floor_of_variation, 0.2, 1e-4) << trial;
    EXPECT_GE(e.l2_of_variation, 0.2 - 1e-4) << trial;
    const auto best = truth_error(
        r, truth,
        (r.U_a.transpose() * (nodes.rowwise() - r.mean_transfer.transpose()).transpose()).transpose());
    EXPECT_GE(best.l2_of_variation, 0.2 - 1e-4) << trial;
  }
  const auto two = truth_error(own, {{1, 2}, nodes.topRows(2)}, MatrixXfR::Zero(2, 2));
  EXPECT_EQ(two.l2_floor, 0);  // two nodes, rank 2: any basis through them fits them
}

// The drawn basis is fitted to the picking half and measured at the reported
// half. Population: a mean plus directions u1, u2 with random coefficients;
// the clusters vary along u1 and u3 only, so their rank-2 basis leaves all of
// u2 at the reported nodes, which the picking half's own basis spans.
TEST(Appearance, DrawnBasisComparisonMeasuresBothBasesAtTheReportedHalf) {
  const Eigen::Index width = 48 * 3;
  std::mt19937_64 rng(11);
  const auto unit = [&] { return static_cast<double>(rng() % 2001) / 1000.0 - 1.0; };
  Eigen::MatrixXd u =
      Eigen::HouseholderQR<Eigen::MatrixXd>(Eigen::MatrixXd::Random(width, 3)).householderQ() *
      Eigen::MatrixXd::Identity(width, 3);
  const Eigen::RowVectorXd mean = Eigen::RowVectorXd::Random(width);
  const auto fields_along = [&](int n, int a, int b, Eigen::MatrixXd& coefficients) {
    coefficients.resize(n, 2);
    MatrixXfR f(n, width);
    for (int i = 0; i < n; ++i) {
      coefficients(i, 0) = 2 * unit(), coefficients(i, 1) = unit();
      f.row(i) =
          (mean + coefficients(i, 0) * u.col(a).transpose() + coefficients(i, 1) * u.col(b).transpose())
              .cast<float>();
    }
    return f;
  };
  Eigen::MatrixXd cc, pc, tc;
  const auto served = reduce_transfer(fields_along(8, 0, 2, cc), {.rank = 2});
  HeldOutTruth picking{{0, 1, 2, 3, 4, 5}, fields_along(6, 0, 1, pc)};
  HeldOutTruth test;  // 20 reported nodes: enough for the paired verdict below
  test.fields = fields_along(20, 0, 1, tc);
  for (int h = 0; h < 20; ++h) test.nodes.push_back(6 + h);
  const auto c = compare_with_drawn_basis(served, picking, test);
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->drawn_fields, 6);
  // The picking half spans the reported half's variation: nothing is left.
  EXPECT_NEAR(c->drawn.of_variation, 0, 1e-4);
  EXPECT_NEAR(c->drawn.l2_of_variation, 0, 1e-4);
  // The clusters' basis leaves the whole u2 part (their mean has none), by hand,
  // relative to the nodes' variation about their own mean.
  const Eigen::MatrixXd centred = tc.rowwise() - tc.colwise().mean();
  EXPECT_NEAR(c->served.of_variation, std::sqrt(tc.col(1).squaredNorm() / centred.squaredNorm()), 1e-4);
  EXPECT_NEAR(c->served.interpolation, 0, 1e-5);  // served at the exact projection: truncation alone
  EXPECT_NEAR(c->served.total, c->served.truncation, 1e-6);
  // Swapped halves the other way round: the picking fields along u1, u3 miss u2 as well.
  HeldOutTruth cluster_like{{0, 1, 2, 3, 4, 5}, fields_along(6, 0, 2, pc)};
  const auto like = compare_with_drawn_basis(served, cluster_like, test);
  EXPECT_GT(like->drawn.of_variation, 0.1);
  // Fitted to other samples of u1 and u3, it misses u2 and fits the common u1
  // part worse than the clusters' 8 fields: no gain.
  EXPECT_LT(like->drawn_gain.gain, 1e-3);
  // The paired verdict: the drawn basis saves all of the clusters' squared
  // truncation at every node, beyond the noise of the paired differences.
  EXPECT_NEAR(c->drawn_gain.gain, 1.0, 1e-4);
  EXPECT_TRUE(c->drawn_gain.beyond_noise());
  // Too few picking fields to resolve r_a directions (two, or three alike), or
  // one reported node: nothing to compare.
  EXPECT_FALSE(compare_with_drawn_basis(served, {{0, 1}, picking.fields.topRows(2)}, test).has_value());
  MatrixXfR alike(3, width);
  alike.rowwise() = picking.fields.row(0);
  EXPECT_FALSE(compare_with_drawn_basis(served, {{0, 1, 2}, alike}, test).has_value());
  EXPECT_FALSE(compare_with_drawn_basis(served, picking, {{6}, test.fields.topRows(1)}).has_value());
  // Fields of another width are an error naming both widths.
  try {
    compare_with_drawn_basis(served, {{0, 1, 2}, MatrixXfR::Zero(3, 48)}, test);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "compare_with_drawn_basis: expected fields of width 144 (48S), got 48");
  }
}

// The spread of the l2 figures over resampled nodes, checked against a dense
// SVD of the resampled columns themselves (the code works on Gram matrices).
TEST(Appearance, HeldOutSpreadIsTheRelativeL2OfResampledNodes) {
  const MatrixXfR fields = fields_with_spectrum({10, 5, 3, 1, 0.5}, 8, 48 * 5);
  const auto r = reduce_transfer(fields, {.rank = 2});
  // Six fresh fields: blends of the clusters, unevenly far from span(U_a).
  HeldOutTruth truth;
  truth.fields.resize(6, fields.cols());
  for (int h = 0; h < 6; ++h) {
    truth.fields.row(h) = (0.2f * static_cast<float>(h)) * fields.row(h) +
                          (1 - 0.1f * static_cast<float>(h)) * fields.row(7 - h);
    truth.nodes.push_back(20 + h);
  }
  const MatrixXfR served = MatrixXfR::Constant(6, 2, 0.5f);
  const std::uint64_t seed = 5;
  const auto one = truth_error_spread(r, truth, served, 1, seed);
  EXPECT_EQ(one.l2_total[0], one.l2_total[1]);  // one draw: both percentiles are it
  // The same draw by hand, and its figures from the columns' singular values.
  std::mt19937_64 rng(seed);
  const Eigen::MatrixXd U = r.U_a.cast<double>();
  Eigen::MatrixXd E(fields.cols(), 6), T(fields.cols(), 6), C(fields.cols(), 6);
  for (int i = 0; i < 6; ++i) {
    const auto h = static_cast<Eigen::Index>(rng() % 6);
    const Eigen::VectorXd d = (truth.fields.row(h) - r.mean_transfer.transpose()).transpose().cast<double>();
    C.col(i) = d;
    T.col(i) = d - U * (U.transpose() * d);
    E.col(i) = d - U * served.row(h).transpose().cast<double>();
  }
  const auto norm2 = [](const Eigen::MatrixXd& X) { return core::spectral_norm(X); };
  EXPECT_NEAR(one.l2_total[0], norm2(E) / norm2(C), 1e-5);
  EXPECT_NEAR(one.l2_truncation[0], norm2(T) / norm2(C), 1e-5);
  // Of the resample's own variation: its columns centred on their own mean (repeats counted).
  const Eigen::MatrixXd own = C.colwise() - C.rowwise().mean();
  ASSERT_TRUE(one.l2_of_variation);
  EXPECT_NEAR((*one.l2_of_variation)[0], norm2(E) / norm2(own), 1e-5);
  EXPECT_GT((*one.l2_of_variation)[0], one.l2_total[0]) << "not vacuous: the two denominators differ";
  // Over many draws the spread is real here and holds the figure over all nodes.
  const auto exact = truth_error(r, truth, served);
  const auto many = truth_error_spread(r, truth, served);
  EXPECT_LT(many.l2_truncation[0], many.l2_truncation[1]);
  EXPECT_LE(many.l2_truncation[0], exact.l2_truncation);
  EXPECT_GE(many.l2_truncation[1], exact.l2_truncation);
  EXPECT_LE(many.l2_total[0], exact.l2_total);
  EXPECT_GE(many.l2_total[1], exact.l2_total);
  ASSERT_TRUE(many.l2_of_variation);
  EXPECT_LT((*many.l2_of_variation)[0], (*many.l2_of_variation)[1]);
  // Nodes that are all alike leave nothing to the draw.
  for (int h = 1; h < 6; ++h) truth.fields.row(h) = truth.fields.row(0);
  const auto alike = truth_error_spread(r, truth, MatrixXfR::Zero(6, 2));
  EXPECT_NEAR(alike.l2_truncation[0], alike.l2_truncation[1], 1e-6);
  EXPECT_NEAR(alike.l2_total[0], 1, 1e-5);  // the mean alone served: the whole deviation
  // No node varies about their mean in any resample: no figure of that
  // variation (J G J leaves only its rounding, which must not be divided by).
  EXPECT_FALSE(alike.l2_of_variation);
  const TruthError alike_error = truth_error(r, truth, MatrixXfR::Zero(6, 2));
  EXPECT_EQ(alike_error.of_variation, 0);
  EXPECT_EQ(alike_error.l2_of_variation, 0);
  EXPECT_GT(alike_error.l2_total, 0.99) << "the nodes do deviate from M-bar";
}

TEST(Appearance, HeldOutSpreadRejectsNoDrawsAndMismatchedServedCoordinates) {
  const MatrixXfR fields = fields_with_spectrum({10, 5, 3}, 6, 48 * 2);
  const auto r = reduce_transfer(fields, {.rank = 2});
  HeldOutTruth truth;
  truth.fields = fields.topRows(3);
  truth.nodes = {10, 11, 12};
  EXPECT_THROW(truth_error_spread(r, truth, MatrixXfR::Zero(3, 2), 0), std::invalid_argument);
  EXPECT_THROW(truth_error_spread(r, truth, MatrixXfR::Zero(2, 2)), std::invalid_argument);
}

TEST(Appearance, HeldOutNodesAreDrawnDeterministicallyAndCapped) {
  const auto a = draw_held_out_nodes(10, {1, 2, 3}, 4, 9);
  EXPECT_EQ(a, draw_held_out_nodes(10, {1, 2, 3}, 4, 9));
  EXPECT_NE(a, draw_held_out_nodes(10, {1, 2, 3}, 4, 10));
  EXPECT_EQ(draw_held_out_nodes(5, {0, 1}, 40, 1).size(), 3u);  // only 3 nodes are not clusters
  EXPECT_TRUE(draw_held_out_nodes(5, {}, 0, 1).empty());
}

// The same states judged at a few picking nodes, half of them outliers:
// cluster sizes still pick better there, but by less than the per-node
// differences can tell apart, so the paper's equal weights are kept.
TEST(Appearance, EqualWeightsAreKeptWhenClusterSizesGainWithinNoise) {
  const MatrixXfR q_u = crowd_and_outliers();
  const auto clusters = kmeans(q_u, {.clusters = 12, .seed = 2});
  HeldOutTruth truth;
  // Picking half (first six): three crowded states, where cluster sizes do
  // better, and three outlying ones, where the two differ by more either way.
  truth.nodes = {0, 5, 10, 360, 365, 366, 16, 21, 26, 361, 362, 364};
  for (auto n : truth.nodes)
    ASSERT_EQ(std::count(clusters.representatives.begin(), clusters.representatives.end(), n), 0);
  truth.fields = feature_fields(q_u, truth.nodes);
  const MatrixXfR fields = feature_fields(q_u, clusters.representatives);
  const auto model = fit_appearance_model(q_u, clusters, fields, {.reduction = {.rank = 2}}, truth);
  ASSERT_TRUE(model.weighting_gain);
  const PairedGain& g = *model.weighting_gain;
  ASSERT_GT(g.gain, 0) << "not vacuous: cluster sizes pick better";
  ASSERT_FALSE(g.beyond_noise()) << g.gain << " vs noise " << g.noise;
  EXPECT_NEAR(g.gain, 0.045, 0.005);   // the figures docs/transfer.md quotes
  EXPECT_NEAR(g.noise, 0.229, 0.005);  // t_0.975 = 2.571 at 5 degrees of freedom
  EXPECT_EQ(model.candidates[0].weighting, TransferWeighting::equal);
  EXPECT_EQ(model.appearance.transfer_weighting, "equal");
  // The equal candidate moved to the front; the others keep their order.
  EXPECT_EQ(model.candidates[1].weighting, TransferWeighting::cluster_size);
  for (size_t i = 2; i < model.candidates.size(); ++i)
    EXPECT_LE(model.candidates[i - 1].selection.of_transfer, model.candidates[i].selection.of_transfer);
  const auto by_equal = fit_appearance_model(
      q_u, clusters, fields, {.reduction = {.rank = 2}, .weighting = WeightingChoice::equal}, truth);
  EXPECT_EQ(model.appearance.mean_transfer, by_equal.appearance.mean_transfer);
  EXPECT_FALSE(by_equal.weighting_gain) << "a forced weighting is not judged";
}

TEST(Appearance, PairedGainIsTheSavedFractionWithItsTInterval) {
  const Eigen::VectorXd same_saving = (Eigen::VectorXd(4) << 4, 4, 4, 4).finished();
  const PairedGain steady = paired_gain(same_saving, same_saving.array() - 1);
  EXPECT_DOUBLE_EQ(steady.gain, 0.25);  // 4 of 16 saved, at every node alike
  EXPECT_DOUBLE_EQ(steady.noise, 0.0);
  EXPECT_TRUE(steady.beyond_noise());
  // Saves 3 at one node and loses 1 at the other: differences 3, -1 (mean 1,
  // sample variance 8), so the 2 of 6 saved has standard error sqrt(8 * 2) / 6
  // and 1 degree of freedom, whose t_0.975 is tan(0.475 pi) (Cauchy).
  const PairedGain mixed = paired_gain(Eigen::Vector2d(4, 2), Eigen::Vector2d(1, 3));
  EXPECT_DOUBLE_EQ(mixed.gain, 2.0 / 6);
  EXPECT_NEAR(mixed.noise, std::tan(0.475 * M_PI) * 4.0 / 6, 1e-9);
  EXPECT_FALSE(mixed.beyond_noise());
  EXPECT_FALSE(paired_gain(Eigen::VectorXd::Constant(1, 5), Eigen::VectorXd::Zero(1)).beyond_noise());
  // A baseline without error leaves nothing to gain: never beyond noise.
  const PairedGain exact = paired_gain(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  EXPECT_EQ(exact.gain, 0);
  EXPECT_TRUE(std::isinf(exact.noise));
  EXPECT_THROW(paired_gain(Eigen::Vector2d(1, 2), Eigen::VectorXd::Zero(3)), std::invalid_argument);
}

// Another N_a must not draw other held-out nodes, or two runs' figures
// measure different states (a harder draw once read as a worse N_a).
TEST(Appearance, HeldOutNodesDoNotDependOnWhichNodesAreClusters) {
  const auto unexcluded = draw_held_out_nodes(1000, {}, 53, 7);
  ASSERT_EQ(unexcluded.size(), 53u);
  // Excluding three drawn nodes (they became representatives) drops exactly
  // those and walks three nodes further; everything else is the same draw.
  const std::vector<std::int32_t> representatives{unexcluded[4], unexcluded[20], unexcluded[49], 999};
  std::vector<std::int32_t> expected;
  for (auto n : unexcluded)
    if (std::find(representatives.begin(), representatives.end(), n) == representatives.end())
      expected.push_back(n);
  EXPECT_EQ(draw_held_out_nodes(1000, representatives, 50, 7), expected);
  // A shorter draw is the start of a longer one.
  const auto shorter = draw_held_out_nodes(1000, representatives, 20, 7);
  EXPECT_TRUE(std::equal(shorter.begin(), shorter.end(), expected.begin()));
}

TEST(Appearance, RejectsMismatchedFields) {
  core::ScenePackage p = testing::make_plate_package({.grid = 4, .appearance = false});
  const auto clusters = kmeans(p.portrait.q_u, {.clusters = 3});
  try {
    fit_appearance_model(p.portrait.q_u, clusters, MatrixXfR::Zero(2, 48 * p.mesh.points()), {});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "fit_appearance_model: expected one transfer field per cluster (3), got 2");
  }
}

}  // namespace
}  // namespace phasecast
