#include "phasecast/precompute/appearance/transfer_reduction.h"

#include "largest_eigenvalue.h"

#include "phasecast/core/package.h"

#include <fmt/format.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

constexpr Eigen::Index kBlock = 4096;  // columns of A_a^T converted to double at a time
constexpr double kResolvable = 1e-6;   // sigma below this fraction of sigma_1: Gram round-off

void check(const Eigen::Ref<const MatrixXfR>& X, const TransferReductionOptions& o,
           const Eigen::VectorXd& weights) {
  if (X.rows() == 0 || X.cols() == 0 || X.cols() % core::kTransferPerPoint != 0) {
    throw std::invalid_argument(fmt::format(
        "reduce_transfer: fields must be N_a x 48S with N_a, S >= 1, got {} x {}", X.rows(), X.cols()));
  }
  if (!(o.eps_a >= 0 && o.eps_a <= 1)) {
    throw std::invalid_argument(fmt::format("reduce_transfer: eps_a must be in [0, 1], got {}", o.eps_a));
  }
  if (o.rank < 0)
    throw std::invalid_argument(fmt::format("reduce_transfer: rank must be >= 0, got {}", o.rank));
  if (weights.size() != 0 && weights.size() != X.rows()) {
    throw std::invalid_argument(fmt::format("reduce_transfer: expected {} weights (one per field), got {}",
                                            X.rows(), weights.size()));
  }
  for (Eigen::Index j = 0; j < weights.size(); ++j) {
    if (!(weights[j] > 0 && std::isfinite(weights[j])))
      throw std::invalid_argument(
          fmt::format("reduce_transfer: weight {} is {}, expected a positive finite value", j, weights[j]));
  }
  for (Eigen::Index j = 0; j < X.rows(); ++j) {
    if (!X.row(j).allFinite()) {
      throw std::invalid_argument(fmt::format("reduce_transfer: field {} has a non-finite value", j));
    }
  }
}

// Centred block of A_a^T in double: rows are fields, columns [begin, begin + width).
Eigen::MatrixXd centred_block(const Eigen::Ref<const MatrixXfR>& X, const Eigen::VectorXd& mean,
                              Eigen::Index begin, Eigen::Index width) {
  Eigen::MatrixXd B = X.middleCols(begin, width).cast<double>();
  B.rowwise() -= mean.segment(begin, width).transpose();
  return B;
}

template <class Body>
void for_blocks(Eigen::Index n, Body body) {
  for (Eigen::Index b = 0; b < n; b += kBlock) body(b, std::min(kBlock, n - b));
}

}  // namespace

TransferReduction reduce_transfer(const Eigen::Ref<const MatrixXfR>& X, const TransferReductionOptions& o,
                                  const Eigen::VectorXd& weights) {
  check(X, o, weights);
  const Eigen::Index Na = X.rows(), n = X.cols();
  const Eigen::VectorXd W = weights.size() ? weights : Eigen::VectorXd::Ones(Na);
  const Eigen::VectorXd root_w = W.cwiseSqrt();
  const Eigen::VectorXd share = W / W.sum();  // M-bar = sum_j share_j M^j
  Eigen::VectorXd mean(n);
  for_blocks(n, [&](Eigen::Index b, Eigen::Index w) {
    const Eigen::MatrixXd block = X.middleCols(b, w).cast<double>();
    // Equal weights keep the plain mean, so unweighted packages stay bit for bit.
    mean.segment(b, w) = weights.size() ? Eigen::VectorXd(block.transpose() * share)
                                        : Eigen::VectorXd(block.colwise().mean().transpose());
  });

  // (A_a W^1/2)^T A_a W^1/2 = sum over column blocks; its eigenpairs give sigma^2 and V.
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(Na, Na);
  for_blocks(n, [&](Eigen::Index b, Eigen::Index w) {
    Eigen::MatrixXd B = centred_block(X, mean, b, w);
    if (weights.size()) B = root_w.asDiagonal() * B;
    gram.noalias() += B * B.transpose();
  });
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  const Eigen::VectorXd lambda = eig.eigenvalues().reverse();
  const Eigen::MatrixXd V = eig.eigenvectors().rowwise().reverse();
  const Eigen::VectorXd sigma = lambda.cwiseMax(0).cwiseSqrt();

  TransferReduction r;
  r.mean_transfer = mean.cast<float>();
  r.singular_values = sigma.cast<float>();
  r.rel_error.resize(Na);
  const double total = sigma.squaredNorm();
  for (Eigen::Index i = 0; i < Na; ++i) {
    const double rest = sigma.tail(Na - i - 1).squaredNorm();
    r.rel_error[i] = static_cast<float>(total > 0 ? std::sqrt(rest / total) : 0.0);
  }

  int resolvable = 0, by_eps = 0;
  for (Eigen::Index i = 0; i < Na && sigma[0] > 0; ++i) {
    if (sigma[i] > kResolvable * sigma[0]) ++resolvable;
    if (sigma[i] >= o.eps_a * sigma[0]) ++by_eps;
  }
  const int rank = std::min(o.rank > 0 ? o.rank : by_eps, resolvable);

  // U_a = A_a W^1/2 V Sigma^-1, then one Cholesky QR step against Gram round-off.
  Eigen::MatrixXd C = V.leftCols(rank);
  for (int i = 0; i < rank; ++i) {
    Eigen::Index big = 0;
    C.col(i).cwiseAbs().maxCoeff(&big);
    if (C(big, i) < 0) C.col(i) = -C.col(i);  // sign convention: largest entry of v_i positive
    if (weights.size()) C.col(i) = C.col(i).cwiseProduct(root_w);
    C.col(i) /= sigma[i];
  }
  Eigen::MatrixXd U(n, rank);
  for_blocks(n, [&](Eigen::Index b, Eigen::Index w) {
    U.middleRows(b, w).noalias() = centred_block(X, mean, b, w).transpose() * C;
  });
  if (rank > 0) {
    const Eigen::LLT<Eigen::MatrixXd> llt(U.transpose() * U);
    U = llt.matrixU().solve<Eigen::OnTheRight>(U);  // U R^-1 with U^T U = R^T R
  }
  // Q_a = U_a^T A_a: the projection of each centred field.
  Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(rank, Na);
  for_blocks(n, [&](Eigen::Index b, Eigen::Index w) {
    Q.noalias() += U.middleRows(b, w).transpose() * centred_block(X, mean, b, w).transpose();
  });
  r.U_a = U.cast<float>();
  r.Q_a = Q.cast<float>();
  r.right_vectors = V;
  r.weights = W;
  r.resolved = resolvable;
  return r;
}

double cluster_truncation_l2(const TransferReduction& r, const std::vector<int>& subset) {
  const Eigen::Index Na = r.right_vectors.rows(), rank = r.rank();
  if (subset.empty() || r.singular_values.size() != Na) {
    throw std::invalid_argument(fmt::format(
        "cluster_truncation_l2: expected a non-empty subset of the {} clusters and their right vectors", Na));
  }
  // Rows S of W^-1/2 V Sigma: the coordinates of the chosen columns of A_a.
  Eigen::MatrixXd coordinates(static_cast<Eigen::Index>(subset.size()), Na);
  for (size_t i = 0; i < subset.size(); ++i) {
    if (subset[i] < 0 || subset[i] >= Na) {
      throw std::invalid_argument(
          fmt::format("cluster_truncation_l2: cluster {} is not in 0..{}", subset[i], Na - 1));
    }
    const double w = r.weights.size() == Na ? r.weights[subset[i]] : 1.0;
    coordinates.row(static_cast<Eigen::Index>(i)) =
        r.right_vectors.row(subset[i]).cwiseProduct(r.singular_values.cast<double>().transpose()) /
        std::sqrt(w);
  }
  const auto largest = [](const Eigen::MatrixXd& X) {  // |X|_2^2 from the smaller Gram matrix
    return largest_eigenvalue(X.rows() <= X.cols() ? Eigen::MatrixXd(X * X.transpose())
                                                   : Eigen::MatrixXd(X.transpose() * X));
  };
  const double data = largest(coordinates);
  if (!(data > 0) || rank >= Na) return 0;  // nothing varies, or nothing is truncated
  return std::sqrt(largest(coordinates.rightCols(Na - rank)) / data);
}

double cluster_truncation_l2(const TransferReduction& r, int columns, int draws, std::uint64_t seed) {
  const auto Na = static_cast<int>(r.right_vectors.rows());
  if (columns < 1 || draws < 1) {
    throw std::invalid_argument(
        fmt::format("cluster_truncation_l2: expected columns and draws >= 1, got {} and {}", columns, draws));
  }
  std::vector<int> all(static_cast<size_t>(Na));
  std::iota(all.begin(), all.end(), 0);
  if (columns >= Na) return cluster_truncation_l2(r, all);
  std::mt19937_64 rng(seed);
  std::vector<double> ratios;
  for (int d = 0; d < draws; ++d) {
    // The first `columns` of a partial Fisher-Yates shuffle (modulo draws: no
    // library distribution, so every platform picks the same subsets).
    for (int i = 0; i < columns; ++i) {
      const auto j = i + static_cast<int>(rng() % static_cast<std::uint64_t>(Na - i));
      std::swap(all[static_cast<size_t>(i)], all[static_cast<size_t>(j)]);
    }
    ratios.push_back(cluster_truncation_l2(r, std::vector<int>(all.begin(), all.begin() + columns)));
  }
  const auto middle = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), middle, ratios.end());
  return *middle;
}

VectorXf held_out_truncation_curve(const Eigen::Ref<const MatrixXfR>& fields, const TransferReduction& r,
                                   const Eigen::Ref<const MatrixXfR>& held_out) {
  const Eigen::Index Na = fields.rows(), n = fields.cols(), H = held_out.rows(), K = r.resolved;
  if (r.mean_transfer.size() != n || (H > 0 && held_out.cols() != n) || r.right_vectors.rows() != Na ||
      r.right_vectors.cols() != Na || r.singular_values.size() != Na || r.weights.size() != Na || K > Na) {
    throw std::invalid_argument(fmt::format(
        "held_out_truncation_curve: expected the {} x {} fields of the reduction and held-out fields of {} "
        "values, got a reduction of {} fields and {} values, and held-out fields of {}",
        Na, n, n, r.right_vectors.rows(), r.mean_transfer.size(), held_out.cols()));
  }
  if (H == 0 || K == 0) return {};
  // All K directions U = A^T W^1/2 V_K Sigma^-1, block by block (never stored),
  // with U^T U for the Cholesky QR step reduce_transfer takes, so that the
  // first r_a directions span what U_a spans to round-off even where sigma is
  // small; C U and C C^T, C the held-out fields less M-bar.
  const Eigen::VectorXd mean = r.mean_transfer.cast<double>();
  const Eigen::MatrixXd Z = r.weights.cwiseSqrt().asDiagonal() * r.right_vectors.leftCols(K) *
                            r.singular_values.head(K).cast<double>().cwiseInverse().asDiagonal();
  Eigen::MatrixXd UtU = Eigen::MatrixXd::Zero(K, K), CU = Eigen::MatrixXd::Zero(H, K);
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(H, H);
  for_blocks(n, [&](Eigen::Index b, Eigen::Index w) {
    const Eigen::MatrixXd U = centred_block(fields, mean, b, w).transpose() * Z;
    const Eigen::MatrixXd C = centred_block(held_out, mean, b, w);
    UtU.noalias() += U.transpose() * U;
    CU.noalias() += C * U;
    gram.noalias() += C * C.transpose();
  });
  const double data = largest_eigenvalue(gram);
  VectorXf curve = VectorXf::Zero(K);
  if (!(data > 0)) return curve;
  // Coordinates on the orthonormalised directions U R^-1 (U^T U = R^T R).
  const Eigen::MatrixXd coordinates = Eigen::LLT<Eigen::MatrixXd>(UtU).matrixU().solve<Eigen::OnTheRight>(CU);
  for (Eigen::Index i = 0; i < K; ++i) {
    gram.noalias() -= coordinates.col(i) * coordinates.col(i).transpose();
    curve[i] = static_cast<float>(std::sqrt(largest_eigenvalue(gram) / data));
  }
  return curve;
}

ResidualByPart residual_by_part(const Eigen::Ref<const MatrixXfR>& X, const VectorXf& mean_f,
                                const MatrixXfR& U_a, const std::vector<std::uint8_t>& deformable) {
  const Eigen::Index n = X.cols();
  const auto S = static_cast<Eigen::Index>(deformable.size());
  if (n != core::kTransferPerPoint * S || mean_f.size() != n || U_a.rows() != n) {
    throw std::invalid_argument(
        fmt::format("residual_by_part: expected fields, mean and U_a of 48 x {} values, got {}, {} and {}", S,
                    n, mean_f.size(), U_a.rows()));
  }
  const Eigen::VectorXd mean = mean_f.cast<double>();
  // The coordinates U_a^T A of every field, then R block by block.
  Eigen::MatrixXd coordinates = Eigen::MatrixXd::Zero(X.rows(), U_a.cols());
  for_blocks(n, [&](Eigen::Index b, Eigen::Index w) {
    coordinates.noalias() += centred_block(X, mean, b, w) * U_a.middleRows(b, w).cast<double>();
  });
  std::array<double, 2> point_data{}, point_residual{};
  std::array<double, 4> band_data{}, band_residual{};
  for_blocks(n, [&](Eigen::Index b, Eigen::Index w) {
    const Eigen::MatrixXd A = centred_block(X, mean, b, w);
    const Eigen::MatrixXd R = A - coordinates * U_a.middleRows(b, w).cast<double>().transpose();
    const Eigen::VectorXd a2 = A.colwise().squaredNorm(), r2 = R.colwise().squaredNorm();
    for (Eigen::Index i = 0; i < w; ++i) {
      const Eigen::Index value = b + i, coefficient = value % 16;
      const size_t kind = deformable[static_cast<size_t>(value / core::kTransferPerPoint)] ? 0 : 1;
      const auto band =
          static_cast<size_t>(std::sqrt(static_cast<double>(coefficient)));  // k in [l^2, (l+1)^2)
      point_data[kind] += a2[i];
      point_residual[kind] += r2[i];
      band_data[band] += a2[i];
      band_residual[band] += r2[i];
    }
  });
  const double data = point_data[0] + point_data[1], residual = point_residual[0] + point_residual[1];
  const auto share = [](double part, double whole) { return whole > 0 ? part / whole : 0.0; };
  const auto part = [&](double d, double r) {
    return PartOfResidual{share(d, data), share(r, residual), d > 0 ? std::sqrt(r / d) : 0.0};
  };
  ResidualByPart out;
  for (size_t k = 0; k < 2; ++k) out.points[k] = part(point_data[k], point_residual[k]);
  for (size_t l = 0; l < 4; ++l) out.bands[l] = part(band_data[l], band_residual[l]);
  out.relative = data > 0 ? std::sqrt(residual / data) : 0.0;
  return out;
}

}  // namespace phasecast::precompute
