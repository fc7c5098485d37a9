#include "phasecast/precompute/reduction/randomized_svd.h"

#include "phasecast/core/dense_svd.h"

#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace phasecast::precompute {
namespace {

using Eigen::Index;
using Eigen::MatrixXf;

// Orthonormal basis of the columns of Y (thin Q of a Householder QR).
MatrixXf orthonormalize(const MatrixXf& Y) {
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Y.cast<double>());
  return (qr.householderQ() * Eigen::MatrixXd::Identity(Y.rows(), Y.cols())).cast<float>();
}

// Calls f(first, block) for consecutive column blocks of A.
template <class F>
void for_each_block(const ColumnSource& A, Index block_columns, F&& f) {
  MatrixXf block;
  for (Index first = 0; first < A.cols(); first += block_columns) {
    const Index count = std::min(block_columns, A.cols() - first);
    A.read(first, count, block);
    f(first, block);
  }
}

// Gaussian test matrix, generated block by block from the seed so that it
// never needs N x l memory beyond the block being used.
MatrixXf gaussian_rows(Index first, Index count, Index l, std::uint64_t seed) {
  MatrixXf G(count, l);
  for (Index i = 0; i < count; ++i) {
    std::mt19937_64 rng(seed ^ (0x9E3779B97F4A7C15ull * static_cast<std::uint64_t>(first + i + 1)));
    std::normal_distribution<float> normal;
    for (Index j = 0; j < l; ++j) G(i, j) = normal(rng);
  }
  return G;
}

}  // namespace

Index block_columns(const RandomizedSvdOptions& o, Index rows) {
  if (o.block_columns > 0) return o.block_columns;
  const auto column_bytes = static_cast<std::size_t>(std::max<Index>(rows, 1)) * sizeof(float);
  return static_cast<Index>(std::max<std::size_t>(1, o.block_bytes / column_bytes));
}

SvdResult randomized_svd(const ColumnSource& A, const RandomizedSvdOptions& o) {
  const Index M = A.rows(), N = A.cols();
  const Index columns = block_columns(o, M);
  if (M == 0 || N == 0) throw std::invalid_argument("randomized_svd: empty matrix");
  if (o.rank < 1) throw std::invalid_argument("randomized_svd: rank must be >= 1");
  const Index r = std::min<Index>(o.rank, std::min(M, N));
  const Index l = std::min<Index>(r + std::max(0, o.oversampling), std::min(M, N));
  const int passes = 2 + 2 * o.power_iterations;
  int pass = 0;
  auto done_pass = [&] {
    if (o.progress) o.progress(++pass, passes);
  };

  // Pass 1: Y = A Omega, and ||A||_F^2 on the way.
  SvdResult result;
  MatrixXf Y = MatrixXf::Zero(M, l);
  for_each_block(A, columns, [&](Index first, const MatrixXf& block) {
    Y.noalias() += block * gaussian_rows(first, block.cols(), l, o.seed);
    result.frobenius_squared += block.cast<double>().squaredNorm();
  });
  done_pass();
  MatrixXf Q = orthonormalize(Y);

  // Power iterations: Q <- orth(A orth(A^T Q)), re-orthonormalised each half
  // step so that rounding does not collapse the small directions.
  for (int it = 0; it < o.power_iterations; ++it) {
    MatrixXf Z(N, l);
    for_each_block(A, columns, [&](Index first, const MatrixXf& block) {
      Z.middleRows(first, block.cols()).noalias() = block.transpose() * Q;
    });
    done_pass();
    Z = orthonormalize(Z);
    Y.setZero();
    for_each_block(A, columns, [&](Index first, const MatrixXf& block) {
      Y.noalias() += block * Z.middleRows(first, block.cols());
    });
    done_pass();
    Q = orthonormalize(Y);
  }

  // Final pass: B = Q^T A (l x N), whose small SVD gives the factors.
  MatrixXf B(l, N);
  for_each_block(A, columns, [&](Index first, const MatrixXf& block) {
    B.middleCols(first, block.cols()).noalias() = Q.transpose() * block;
  });
  done_pass();
  const core::DenseSvd svd = core::dense_svd(B.cast<double>());
  result.U = Q * svd.U.leftCols(r).cast<float>();
  result.sigma = svd.sigma.head(r).cast<float>();
  result.V = svd.V.leftCols(r).cast<float>();
  return result;
}

int select_rank(const Eigen::VectorXf& sigma, double eps) {
  if (sigma.size() == 0) throw std::invalid_argument("select_rank: no singular values");
  int r = 1;
  while (r < sigma.size() && sigma[r] >= eps * sigma[0]) ++r;
  return r;
}

Eigen::VectorXf relative_error_curve(const Eigen::VectorXf& sigma, double frobenius_squared) {
  Eigen::VectorXf curve(sigma.size());
  double kept = 0;
  for (Index i = 0; i < sigma.size(); ++i) {
    kept += static_cast<double>(sigma[i]) * sigma[i];
    const double rest = std::max(0.0, frobenius_squared - kept);
    curve[i] = frobenius_squared > 0 ? static_cast<float>(std::sqrt(rest / frobenius_squared)) : 0.0f;
  }
  return curve;
}

}  // namespace phasecast::precompute
