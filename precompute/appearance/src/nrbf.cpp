#include "phasecast/precompute/appearance/nrbf.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace phasecast::precompute {
namespace {

using MatrixXdR = RowMatrix<double>;

void check_fit(const Eigen::Ref<const MatrixXfR>& C, const Eigen::Ref<const VectorXf>& w,
               const Eigen::Ref<const MatrixXfR>& values, float lambda) {
  if (C.rows() == 0 || C.cols() == 0) {
    throw std::invalid_argument(
        fmt::format("nrbf: centers must be N_a x r_u with N_a, r_u >= 1, got {} x {}", C.rows(), C.cols()));
  }
  if (w.size() != C.rows()) {
    throw std::invalid_argument(
        fmt::format("nrbf: expected {} widths (one per centre), got {}", C.rows(), w.size()));
  }
  if (values.rows() != C.rows()) {
    throw std::invalid_argument(
        fmt::format("nrbf: values must have {} rows (one per centre), got {}", C.rows(), values.rows()));
  }
  if (!C.allFinite()) throw std::invalid_argument("nrbf: centers must be finite");
  if (!values.allFinite()) throw std::invalid_argument("nrbf: values must be finite");
  for (Eigen::Index j = 0; j < w.size(); ++j) {
    if (!(w[j] > 0 && std::isfinite(w[j]))) {
      throw std::invalid_argument(fmt::format("nrbf: width {} must be positive and finite, got {}", j, w[j]));
    }
  }
  if (!(lambda >= 0 && std::isfinite(lambda))) {
    throw std::invalid_argument(fmt::format("nrbf: regularization must be finite and >= 0, got {}", lambda));
  }
}

// Normalized basis row phi(q). Exponents are shifted by their minimum so
// that a query far from every centre still normalizes (no 0/0).
Eigen::RowVectorXd basis(const MatrixXdR& C, const Eigen::VectorXd& w, const Eigen::RowVectorXd& q) {
  Eigen::RowVectorXd e(C.rows());
  for (Eigen::Index j = 0; j < C.rows(); ++j) e[j] = (q - C.row(j)).squaredNorm() / (2 * w[j] * w[j]);
  const Eigen::RowVectorXd phi = (-(e.array() - e.minCoeff())).exp().matrix();
  return phi / phi.sum();
}

MatrixXdR basis_matrix(const MatrixXdR& C, const Eigen::VectorXd& w, const MatrixXdR& Q) {
  MatrixXdR Phi(Q.rows(), C.rows());
  for (Eigen::Index i = 0; i < Q.rows(); ++i) Phi.row(i) = basis(C, w, Q.row(i));
  return Phi;
}

// (Phi^T Phi + lambda I) W = Phi^T V
MatrixXdR solve_weights(const MatrixXdR& Phi, const MatrixXdR& V, double lambda) {
  if (V.cols() == 0)
    return MatrixXdR(Phi.cols(), 0);  // r_a = 0: nothing to fit (Eigen solvers need a column)
  Eigen::MatrixXd lhs = Phi.transpose() * Phi;
  lhs.diagonal().array() += lambda;
  const Eigen::MatrixXd rhs = Phi.transpose() * V;
  if (lambda > 0) return Eigen::LDLT<Eigen::MatrixXd>(lhs).solve(rhs);
  // lambda = 0: plain interpolation, Phi W = V, by a rank-revealing solve.
  return Phi.colPivHouseholderQr().solve(V);
}

}  // namespace

VectorXf nrbf_widths(const Eigen::Ref<const MatrixXfR>& q_u, const std::vector<std::int32_t>& labels,
                     const Eigen::Ref<const MatrixXfR>& centers, float scale) {
  const Eigen::Index Na = centers.rows();
  if (static_cast<Eigen::Index>(labels.size()) != q_u.rows() || q_u.cols() != centers.cols()) {
    throw std::invalid_argument(
        fmt::format("nrbf_widths: expected {} labels and q_u with {} columns, got {} labels and {} x {}",
                    q_u.rows(), centers.cols(), labels.size(), q_u.rows(), q_u.cols()));
  }
  if (!(scale > 0 && std::isfinite(scale))) {
    throw std::invalid_argument(fmt::format("nrbf_widths: scale must be positive, got {}", scale));
  }
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(Na), count = Eigen::VectorXd::Zero(Na);
  for (Eigen::Index i = 0; i < q_u.rows(); ++i) {
    const auto j = labels[static_cast<size_t>(i)];
    if (j < 0 || j >= Na) {
      throw std::invalid_argument(
          fmt::format("nrbf_widths: label {} of node {} is not a cluster 0..{}", j, i, Na - 1));
    }
    sum[j] += (q_u.row(i) - centers.row(j)).cast<double>().squaredNorm();
    count[j] += 1;
  }
  VectorXf w(Na);
  for (Eigen::Index j = 0; j < Na; ++j) {
    double spread = count[j] > 0 ? std::sqrt(sum[j] / count[j]) : 0;
    if (!(spread > 0)) {
      double nearest = std::numeric_limits<double>::infinity();
      for (Eigen::Index k = 0; k < Na; ++k) {
        const double d = (centers.row(k) - centers.row(j)).cast<double>().norm();
        if (k != j && d > 0) nearest = std::min(nearest, d);
      }
      spread = std::isfinite(nearest) ? nearest / 2 : 1.0;
    }
    w[j] = static_cast<float>(scale * spread);
  }
  return w;
}

NrbfInterpolant fit_nrbf(const Eigen::Ref<const MatrixXfR>& centers, const Eigen::Ref<const VectorXf>& widths,
                         const Eigen::Ref<const MatrixXfR>& values, float regularization) {
  check_fit(centers, widths, values, regularization);
  const MatrixXdR C = centers.cast<double>();
  const Eigen::VectorXd w = widths.cast<double>();
  const MatrixXdR Phi = basis_matrix(C, w, C);
  NrbfInterpolant f;
  f.centers = centers;
  f.widths = widths;
  f.regularization = regularization;
  f.weights = solve_weights(Phi, values.cast<double>(), regularization).cast<float>();
  return f;
}

MatrixXfR evaluate_nrbf(const NrbfInterpolant& f, const Eigen::Ref<const MatrixXfR>& q) {
  if (q.cols() != f.centers.cols()) {
    throw std::invalid_argument(
        fmt::format("nrbf: queries must have {} columns (r_u), got {}", f.centers.cols(), q.cols()));
  }
  if (!q.allFinite()) throw std::invalid_argument("nrbf: queries must be finite");
  const MatrixXdR Phi = basis_matrix(f.centers.cast<double>(), f.widths.cast<double>(), q.cast<double>());
  return (Phi * f.weights.cast<double>()).cast<float>();
}

LeaveOneOut nrbf_leave_one_out(const Eigen::Ref<const MatrixXfR>& centers,
                               const Eigen::Ref<const VectorXf>& widths,
                               const Eigen::Ref<const MatrixXfR>& values, float regularization) {
  check_fit(centers, widths, values, regularization);
  const Eigen::Index Na = centers.rows();
  if (Na < 2) throw std::invalid_argument("nrbf: leave-one-out needs at least 2 samples, got 1");
  LeaveOneOut out;
  out.errors.resize(Na);
  // N_a refits of N_a - 1 samples, each O(N_a^3): O(N_a^4), minutes at N_a = 800.
  // They are independent, so they run side by side; each error has its own slot
  // and the sums below are taken in order, so the result is the same on any
  // number of threads.
  std::vector<double> errors(static_cast<size_t>(Na));
  tbb::parallel_for(Eigen::Index{0}, Na, [&](Eigen::Index j) {
    MatrixXfR C(Na - 1, centers.cols()), V(Na - 1, values.cols());
    VectorXf w(Na - 1);
    for (Eigen::Index i = 0, k = 0; i < Na; ++i) {
      if (i == j) continue;
      C.row(k) = centers.row(i);
      V.row(k) = values.row(i);
      w[k++] = widths[i];
    }
    const auto f = fit_nrbf(C, w, V, regularization);
    errors[static_cast<size_t>(j)] = (evaluate_nrbf(f, centers.row(j)) - values.row(j)).cast<double>().norm();
  });
  double err2 = 0, norm2 = 0;
  for (Eigen::Index j = 0; j < Na; ++j) {
    const double e = errors[static_cast<size_t>(j)];
    out.errors[j] = static_cast<float>(e);
    err2 += e * e;
    norm2 += values.row(j).cast<double>().squaredNorm();
  }
  out.rms = std::sqrt(err2 / static_cast<double>(Na));
  out.relative = norm2 > 0 ? std::sqrt(err2 / norm2) : 0;
  return out;
}

}  // namespace phasecast::precompute
