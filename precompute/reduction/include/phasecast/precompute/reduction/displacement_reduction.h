#pragma once
// Displacement model reduction (§2.3.1, eqs. 3-7) straight from an orbit store
// on disk: the mean shape x-bar in a first streaming pass, then the
// randomized SVD of A_u = [x^1 - x-bar, ..., x^N - x-bar] reading frames in
// blocks (hyperslabs), so the 3V x N matrix is never held in memory.

#include "phasecast/core/eigen_types.h"
#include "phasecast/precompute/reduction/randomized_svd.h"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>

namespace phasecast::precompute {

// A_u of an orbit store file, one column per frame, streamed from /frames/positions.
class OrbitDisplacementSource final : public ColumnSource {
 public:
  // Opens the store and computes the mean shape (one pass over the frames).
  // Throws OrbitStoreError naming the file for a missing or malformed dataset or a NaN.
  explicit OrbitDisplacementSource(const std::filesystem::path& store);
  ~OrbitDisplacementSource() override;
  OrbitDisplacementSource(const OrbitDisplacementSource&) = delete;
  OrbitDisplacementSource& operator=(const OrbitDisplacementSource&) = delete;

  Eigen::Index rows() const override { return mean_.size(); }
  Eigen::Index cols() const override { return frames_; }
  void read(Eigen::Index first, Eigen::Index count, Eigen::MatrixXf& block) const override;
  const Eigen::VectorXf& mean_shape() const { return mean_; }  // x-bar, 3V
  // Frames [first, first + count) as rows (count x 3V), as stored (the appearance
  // stage reads the unreduced meshes of its cluster nodes through this).
  void read_frames(Eigen::Index first, Eigen::Index count, MatrixXfR& rows) const;

 private:
  void read_into(Eigen::Index first, Eigen::Index count, float* out) const;

  struct Hdf5;
  std::unique_ptr<Hdf5> h5_;
  std::filesystem::path path_;
  Eigen::Index frames_ = 0;
  Eigen::VectorXf mean_;
};

struct ReductionOptions {
  double eps_u = 0.01;  // r_u = largest r with sigma_r >= eps_u sigma_1 (§2.3.1)
  int rank = 0;         // > 0: fixed r_u (eps_u is then recorded as 0)
  int max_rank = 60;    // singular triplets computed (n_sigma of the error curve)
  int power_iterations = 2;
  int oversampling = 10;
  std::uint64_t seed = 1;
  std::function<void(int, int)> progress;  // passes over the frames done / total
};

struct DisplacementBasis {
  Eigen::VectorXf mean_shape;       // 3V
  Eigen::MatrixXf U_u;              // 3V x r_u, orthonormal columns
  Eigen::VectorXf singular_values;  // n_sigma computed, decreasing
  Eigen::VectorXf rel_error;        // n_sigma: ||A - A_r||_F / ||A||_F at r = i + 1 (Fig. 12)
  MatrixXfR q_u;                    // N x r_u: rows of Q_u^T, Q_u = S V^T (eq. 6)
  double eps_u = 0;                 // tolerance used (0: fixed rank)

  int rank() const { return static_cast<int>(U_u.cols()); }
};

// Throws std::invalid_argument naming --rank, --max-rank and --eps-u.
void check_reduction_options(const ReductionOptions& options);

// Rank selection and Q_u = S V^T from the streamed SVD. Throws std::invalid_argument for bad options.
DisplacementBasis reduce_displacements(const OrbitDisplacementSource& A, const ReductionOptions& options);

}  // namespace phasecast::precompute
