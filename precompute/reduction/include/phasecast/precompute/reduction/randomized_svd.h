#pragma once
// Output-sensitive rank-r SVD of the displacement matrix A_u (eqs. 3-4, §2.3.1):
// a randomized range finder with power iterations (Halko, Martinsson & Tropp
// 2011), O(M N r) work, streaming over column blocks so that the M x N matrix
// is never held in memory: only M x l and l x N panels (l = r + oversampling).

#include "phasecast/core/eigen_types.h"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <functional>

namespace phasecast::precompute {

// A column-block view of a matrix A (rows x cols) that can be read in order,
// as many times as the algorithm needs (2 + 2 q passes for q power iterations).
class ColumnSource {
 public:
  virtual ~ColumnSource() = default;
  virtual Eigen::Index rows() const = 0;
  virtual Eigen::Index cols() const = 0;
  // Fills `block` (rows x count) with columns [first, first + count).
  virtual void read(Eigen::Index first, Eigen::Index count, Eigen::MatrixXf& block) const = 0;
};

// A ColumnSource over a matrix already in memory (tests, small problems).
class MatrixColumnSource final : public ColumnSource {
 public:
  explicit MatrixColumnSource(const Eigen::MatrixXf& A) : A_(A) {}
  Eigen::Index rows() const override { return A_.rows(); }
  Eigen::Index cols() const override { return A_.cols(); }
  void read(Eigen::Index first, Eigen::Index count, Eigen::MatrixXf& block) const override {
    block = A_.middleCols(first, count);
  }

 private:
  const Eigen::MatrixXf& A_;
};

struct RandomizedSvdOptions {
  int rank = 30;             // r: number of singular triplets wanted
  int oversampling = 10;     // p: extra random directions (l = r + p)
  int power_iterations = 2;  // q: sharpen a slowly decaying spectrum
  // Columns read at a time; 0: as many as fit in block_bytes (at least one).
  // Sized in bytes so that the one block held stays small whatever 3V is: 2048
  // columns of the paper cloth's 3V = 9 996 were 82 MB, and it was read twice.
  Eigen::Index block_columns = 0;
  std::size_t block_bytes = std::size_t{16} << 20;
  std::uint64_t seed = 1;
  // Called after each pass over the columns with (pass, total passes).
  std::function<void(int, int)> progress;
};

struct SvdResult {
  Eigen::MatrixXf U;             // rows x r, orthonormal columns
  Eigen::VectorXf sigma;         // r, decreasing
  Eigen::MatrixXf V;             // cols x r, orthonormal columns
  double frobenius_squared = 0;  // ||A||_F^2, exact, for the error curve
};

// Columns per block for A's row count under `options` (block_columns, else block_bytes of floats).
Eigen::Index block_columns(const RandomizedSvdOptions& options, Eigen::Index rows);

// Rank-r approximation A ~ U diag(sigma) V^T. Holds one block of A, the
// rows x l panels Y, Q and the l x cols panels Z, B: O((rows + cols) l) floats
// besides the block, never A itself (tests/precompute/reduction/reduction_memory_test.cpp).
SvdResult randomized_svd(const ColumnSource& A, const RandomizedSvdOptions& options);

// Largest r with sigma_r >= eps * sigma_1 (§2.3.1); at least 1, at most sigma.size().
int select_rank(const Eigen::VectorXf& sigma, double eps);

// Relative Frobenius error ||A - A_r||_F / ||A||_F for r = 1..sigma.size() (Fig. 12),
// from the exact ||A||_F^2 and the computed singular values.
Eigen::VectorXf relative_error_curve(const Eigen::VectorXf& sigma, double frobenius_squared);

}  // namespace phasecast::precompute
