#include "phasecast/precompute/appearance/transfer_appearance.h"

#include <fmt/format.h>

#include <stdexcept>

namespace phasecast::precompute {

AppearanceModel fit_appearance_model(const Eigen::Ref<const MatrixXfR>& q_u, const KMeansResult& clusters,
                                     const Eigen::Ref<const MatrixXfR>& fields, const AppearanceOptions& o) {
  const auto Na = static_cast<Eigen::Index>(clusters.representatives.size());
  if (Na == 0 || fields.rows() != Na) {
    throw std::invalid_argument(fmt::format(
        "fit_appearance_model: expected one transfer field per cluster ({}), got {}", Na, fields.rows()));
  }
  if (static_cast<Eigen::Index>(clusters.labels.size()) != q_u.rows()) {
    throw std::invalid_argument(fmt::format("fit_appearance_model: clusters label {} nodes but q_u has {}",
                                            clusters.labels.size(), q_u.rows()));
  }
  MatrixXfR centers(Na, q_u.cols());
  for (Eigen::Index j = 0; j < Na; ++j) {
    const auto node = clusters.representatives[static_cast<size_t>(j)];
    if (node < 0 || node >= q_u.rows()) {
      throw std::invalid_argument(fmt::format(
          "fit_appearance_model: representative {} is node {}, expected 0..{}", j, node, q_u.rows() - 1));
    }
    centers.row(j) = q_u.row(node);
  }

  const TransferReduction reduction = reduce_transfer(fields, o.reduction);  // §4.2: A_a ~ U_a Q_a
  const VectorXf widths = nrbf_widths(q_u, clusters.labels, centers, o.width_scale);
  const MatrixXfR samples = reduction.Q_a.transpose();                                // q_a^j at centre j
  const NrbfInterpolant nrbf = fit_nrbf(centers, widths, samples, o.regularization);  // §4.3

  AppearanceModel m;
  m.q_a = evaluate_nrbf(nrbf, q_u);
  if (Na >= 2) m.leave_one_out = nrbf_leave_one_out(centers, widths, samples, o.regularization);
  core::Appearance& a = m.appearance;
  a.mean_transfer = reduction.mean_transfer;
  a.U_a = reduction.U_a;
  a.singular_values = reduction.singular_values;
  a.rel_error = reduction.rel_error;
  a.cluster_nodes = clusters.representatives;
  a.nrbf_centers = nrbf.centers;
  a.nrbf_weights = nrbf.weights;
  a.nrbf_widths = nrbf.widths;
  a.nrbf_regularization = nrbf.regularization;
  return m;
}

}  // namespace phasecast::precompute
