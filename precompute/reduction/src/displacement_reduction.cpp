#include "phasecast/precompute/reduction/displacement_reduction.h"

#include "phasecast/precompute/sampling/orbit_store.h"

#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

namespace phasecast::precompute {

namespace h5 = core::h5;

struct OrbitDisplacementSource::Hdf5 {
  h5::File file;
};

namespace {
constexpr const char* kPositions = "/frames/positions";
constexpr Eigen::Index kBlockFrames = 512;  // frames per hyperslab read
}  // namespace

OrbitDisplacementSource::OrbitDisplacementSource(const std::filesystem::path& store) : path_(store) {
  if (!std::filesystem::exists(store)) throw OrbitStoreError(fmt::format("{}: no such file", store.string()));
  try {
    h5_ = std::make_unique<Hdf5>(Hdf5{h5::File::open_read(store)});
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}", store.string(), e.what()));
  }
  const h5::Reader r = h5::checked_reader<OrbitStoreError>(h5_->file, store.string());
  if (!h5_->file.exists(kPositions)) r.fail(kPositions, "missing dataset (expected N x 3V float32 frames)");
  const auto dims = r.require(kPositions, h5::Dtype::f32, 2).dims;
  if (dims[0] == 0 || dims[1] == 0 || dims[1] % 3 != 0)
    r.fail(kPositions, "expected a non-empty N x 3V float32 dataset");
  frames_ = static_cast<Eigen::Index>(dims[0]);
  mean_.resize(static_cast<Eigen::Index>(dims[1]));
  // First pass: x-bar, accumulated in double so the mean does not depend on block size.
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(mean_.size());
  MatrixXfR rows;
  for (Eigen::Index first = 0; first < frames_; first += kBlockFrames) {
    read_frames(first, std::min(kBlockFrames, frames_ - first), rows);
    if (!rows.allFinite())
      r.fail(kPositions, fmt::format("NaN or Inf in frames {}..{}", first, first + rows.rows() - 1));
    sum += rows.cast<double>().colwise().sum().transpose();
  }
  mean_ = (sum / static_cast<double>(frames_)).cast<float>();
}

OrbitDisplacementSource::~OrbitDisplacementSource() = default;

void OrbitDisplacementSource::read_frames(Eigen::Index first, Eigen::Index count, MatrixXfR& rows) const {
  rows.resize(count, mean_.size());
  read_into(first, count, rows.data());
}

// `out` holds count x 3V floats: frames as rows, which is the same memory as
// frames as the columns of a column-major 3V x count block.
void OrbitDisplacementSource::read_into(Eigen::Index first, Eigen::Index count, float* out) const {
  try {
    h5_->file.read_rows(kPositions, static_cast<std::uint64_t>(first), static_cast<std::uint64_t>(count),
                        out);
  } catch (const h5::Failure& e) {
    throw OrbitStoreError(fmt::format("{}: {}: cannot read frames {}..{}: {}", path_.string(), kPositions,
                                      first, first + count - 1, e.what()));
  }
}

// Read in place and centred in place: the block is the only copy of its frames.
void OrbitDisplacementSource::read(Eigen::Index first, Eigen::Index count, Eigen::MatrixXf& block) const {
  block.resize(mean_.size(), count);
  read_into(first, count, block.data());
  block.colwise() -= mean_;
}

void check_reduction_options(const ReductionOptions& o) {
  if (o.rank < 0 || o.max_rank < 1 || !(o.eps_u >= 0 && o.eps_u < 1)) {
    throw std::invalid_argument(
        fmt::format("reduction: expected --rank >= 0, --max-rank >= 1 and --eps-u in [0, 1), got {}, {}, {}",
                    o.rank, o.max_rank, o.eps_u));
  }
}

DisplacementBasis reduce_displacements(const OrbitDisplacementSource& A, const ReductionOptions& o) {
  check_reduction_options(o);
  RandomizedSvdOptions svd;
  svd.rank = std::max(o.max_rank, o.rank);
  svd.oversampling = o.oversampling;
  svd.power_iterations = o.power_iterations;
  svd.seed = o.seed;
  svd.progress = o.progress;
  const SvdResult r = randomized_svd(A, svd);
  DisplacementBasis b;
  b.mean_shape = A.mean_shape();
  b.singular_values = r.sigma;
  b.rel_error = relative_error_curve(r.sigma, r.frobenius_squared);
  // A motionless orbit set has sigma_1 = 0: keep one (zero-motion) direction.
  const int ru =
      o.rank > 0 ? std::min(o.rank, static_cast<int>(r.sigma.size())) : select_rank(r.sigma, o.eps_u);
  b.eps_u = o.rank > 0 ? 0.0 : o.eps_u;
  b.U_u = r.U.leftCols(ru);
  // Q_u = S V^T (eq. 6): row k of q_u is (V_k . sigma) for the first r_u triplets.
  b.q_u = (r.V.leftCols(ru) * r.sigma.head(ru).asDiagonal());
  return b;
}

}  // namespace phasecast::precompute
