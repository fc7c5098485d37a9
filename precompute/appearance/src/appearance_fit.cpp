// The appearance model a package holds (§4.2-4.3; appearance_fit.h).

#include "phasecast/precompute/appearance/appearance_fit.h"

#include <fmt/format.h>

#include <stdexcept>

namespace phasecast::precompute {
namespace {

// nrbf: width scale, lambda; knn: k; affine-knn(-slope): k, then the affine map row by row.
VectorXf interpolant_parameters(const Interpolant& f) {
  if (f.kind == InterpolantKind::nrbf)
    return (VectorXf(2) << f.width_scale, f.nrbf.regularization).finished();
  VectorXf v(1 + (has_affine_map(f.kind) ? f.affine.size() : 0));
  v[0] = static_cast<float>(f.neighbours);
  v.tail(v.size() - 1) = Eigen::Map<const VectorXf>(f.affine.data(), f.affine.size());
  return v;
}

}  // namespace

const char* weighting_name(TransferWeighting weighting) {
  return weighting == TransferWeighting::cluster_size ? "cluster size" : "equal";
}

Eigen::VectorXd cluster_size_weights(const KMeansResult& clusters) {
  const auto Na = static_cast<Eigen::Index>(clusters.representatives.size());
  Eigen::VectorXd count = Eigen::VectorXd::Zero(Na);
  for (const auto label : clusters.labels) {
    if (label < 0 || label >= Na)
      throw std::invalid_argument(
          fmt::format("cluster_size_weights: label {} is not a cluster in 0..{}", label, Na - 1));
    count[label] += 1;
  }
  count = count.cwiseMax(1.0);
  return count * (static_cast<double>(Na) / count.sum());
}

MatrixXfR cluster_centers(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters) {
  const auto Na = static_cast<Eigen::Index>(clusters.representatives.size());
  MatrixXfR centers(Na, q_u.cols());
  for (Eigen::Index j = 0; j < Na; ++j) {
    const auto node = clusters.representatives[static_cast<size_t>(j)];
    if (node < 0 || node >= q_u.rows()) {
      throw std::invalid_argument(fmt::format(
          "fit_appearance_model: representative {} is node {}, expected 0..{}", j, node, q_u.rows() - 1));
    }
    centers.row(j) = q_u.row(node);
  }
  return centers;
}

std::vector<Interpolant> tune_interpolants(const Eigen::Ref<const MatrixXfR>& q_u,
                                           const KMeansResult& clusters, const MatrixXfR& centers,
                                           const MatrixXfR& samples, InterpolantChoice choice,
                                           const std::function<void(const char*, long, long)>& progress) {
  std::vector<Interpolant> out;
  const bool all = choice == InterpolantChoice::best;
  if (all || choice == InterpolantChoice::nrbf)
    out.push_back(tune_nrbf(q_u, clusters.labels, centers, samples, progress));
  if (all || choice == InterpolantChoice::knn) out.push_back(tune_knn(centers, samples));
  if (all || choice == InterpolantChoice::affine_knn) out.push_back(tune_affine_knn(centers, samples));
  if (all || choice == InterpolantChoice::affine_knn_slope)
    out.push_back(tune_affine_knn(centers, samples, NeighbourMetric::slope));
  return out;
}

void store_model(core::Appearance& a, const TransferReduction& reduction, TransferWeighting weighting,
                 const Interpolant& f, const KMeansResult& clusters) {
  a.mean_transfer = reduction.mean_transfer;
  a.U_a = reduction.U_a;
  a.cluster_nodes = clusters.representatives;
  a.interpolant = interpolant_name(f.kind);
  a.interpolant_parameters = interpolant_parameters(f);
  a.nrbf_centers = f.nrbf.centers;
  a.nrbf_weights = f.nrbf.weights;
  a.nrbf_widths = f.nrbf.widths;
  a.nrbf_regularization = f.nrbf.regularization;
  a.transfer_weighting = weighting_name(weighting);
}

}  // namespace phasecast::precompute
