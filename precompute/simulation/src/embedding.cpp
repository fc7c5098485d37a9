#include "phasecast/precompute/simulation/embedding.h"

#include <fmt/format.h>

#include <stdexcept>

namespace phasecast::precompute {

bool embeds(const VertexEmbedding& W, Eigen::Index p) {
  return static_cast<bool>(VertexEmbedding::InnerIterator(W, p));
}

MatrixXfR embed_rows(const VertexEmbedding& W, const Eigen::Ref<const MatrixXfR>& rows) {
  if (rows.rows() != 3 * W.cols()) {
    throw std::invalid_argument(fmt::format("embedding over {} vertices applied to {} rows (expected {})",
                                            W.cols(), rows.rows(), 3 * W.cols()));
  }
  MatrixXfR out = MatrixXfR::Zero(3 * W.rows(), rows.cols());
  Eigen::RowVectorXd sum(rows.cols());
  for (Eigen::Index p = 0; p < W.rows(); ++p) {
    for (int c = 0; c < 3; ++c) {
      // Each sum starts from its first term, not from +0: a copied vertex
      // (one weight 1) keeps its -0 entries, so packages without render
      // meshes stay bit for bit what they were.
      bool first = true;
      for (VertexEmbedding::InnerIterator it(W, p); it; ++it) {
        const auto term = it.value() * rows.row(3 * it.col() + c).cast<double>();
        if (first) {
          sum = term;
        } else {
          sum += term;
        }
        first = false;
      }
      if (!first) out.row(3 * p + c) = sum.cast<float>();
    }
  }
  return out;
}

MatrixXfR embed_positions(const VertexEmbedding& W, const PointOffsets& d,
                          const Eigen::Ref<const MatrixXfR>& x) {
  MatrixXfR out = embed_rows(W, x);
  // Only where an offset is: adding +0 elsewhere would turn -0 into +0 and
  // change packages without tubes.
  for (const auto& [p, offset] : d)
    for (int c = 0; c < 3; ++c) out.row(3 * p + c).array() += static_cast<float>(offset(c));
  return out;
}

}  // namespace phasecast::precompute
