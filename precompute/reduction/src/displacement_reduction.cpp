#include "phasecast/precompute/reduction/displacement_reduction.h"

#include "phasecast/precompute/sampling/orbit_store.h"

#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>

#include <hdf5.h>

#include <algorithm>
#include <stdexcept>

namespace phasecast::precompute {

namespace h5 = core::h5;

struct OrbitDisplacementSource::Hdf5 {
  h5::Handle file;
  h5::Handle dataset;
};

namespace {
constexpr const char* kPositions = "/frames/positions";
constexpr Eigen::Index kBlockFrames = 512;  // frames per hyperslab read
}  // namespace

OrbitDisplacementSource::OrbitDisplacementSource(const std::filesystem::path& store)
    : h5_(std::make_unique<Hdf5>()), path_(store) {
  const auto fail = [&](const std::string& what) {
    throw OrbitStoreError(fmt::format("{}: {}: {}", store.string(), kPositions, what));
  };
  if (!std::filesystem::exists(store)) throw OrbitStoreError(fmt::format("{}: no such file", store.string()));
  {
    // Shape and dtype through the checked layer first (it also silences HDF5's error printer).
    try {
      const h5::File f = h5::File::open_read(store);
      if (!f.exists(kPositions)) fail("missing dataset (expected N x 3V float32 frames)");
      const auto info = f.info(kPositions);
      if (info.dtype != h5::Dtype::f32 || info.dims.size() != 2 || info.dims[0] == 0 || info.dims[1] == 0 ||
          info.dims[1] % 3 != 0) {
        fail("expected a non-empty N x 3V float32 dataset");
      }
      frames_ = static_cast<Eigen::Index>(info.dims[0]);
      mean_.resize(static_cast<Eigen::Index>(info.dims[1]));
    } catch (const h5::Failure& e) {
      throw OrbitStoreError(fmt::format("{}: {}", store.string(), e.what()));
    }
  }
  h5_->file = h5::Handle(H5Fopen(store.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (h5_->file.get() < 0) throw OrbitStoreError(fmt::format("{}: cannot open", store.string()));
  h5_->dataset = h5::Handle(H5Dopen2(h5_->file.get(), kPositions, H5P_DEFAULT), H5Dclose);
  if (h5_->dataset.get() < 0) fail("cannot open");
  // First pass: x-bar, accumulated in double so the mean does not depend on block size.
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(mean_.size());
  MatrixXfR rows;
  for (Eigen::Index first = 0; first < frames_; first += kBlockFrames) {
    read_frames(first, std::min(kBlockFrames, frames_ - first), rows);
    if (!rows.allFinite()) fail(fmt::format("NaN or Inf in frames {}..{}", first, first + rows.rows() - 1));
    sum += rows.cast<double>().colwise().sum().transpose();
  }
  mean_ = (sum / static_cast<double>(frames_)).cast<float>();
}

OrbitDisplacementSource::~OrbitDisplacementSource() = default;

void OrbitDisplacementSource::read_frames(Eigen::Index first, Eigen::Index count, MatrixXfR& rows) const {
  rows.resize(count, mean_.size());
  const hsize_t start[2] = {static_cast<hsize_t>(first), 0};
  const hsize_t size[2] = {static_cast<hsize_t>(count), static_cast<hsize_t>(mean_.size())};
  const h5::Handle file_space(H5Dget_space(h5_->dataset.get()), H5Sclose);
  const h5::Handle memory_space(H5Screate_simple(2, size, nullptr), H5Sclose);
  if (file_space.get() < 0 || memory_space.get() < 0 ||
      H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, nullptr, size, nullptr) < 0 ||
      H5Dread(h5_->dataset.get(), H5T_NATIVE_FLOAT, memory_space.get(), file_space.get(), H5P_DEFAULT,
              rows.data()) < 0) {
    throw OrbitStoreError(fmt::format("{}: {}: cannot read frames {}..{}", path_.string(), kPositions, first,
                                      first + count - 1));
  }
}

void OrbitDisplacementSource::read(Eigen::Index first, Eigen::Index count, Eigen::MatrixXf& block) const {
  MatrixXfR rows;
  read_frames(first, count, rows);
  block = (rows.transpose().colwise() - mean_);
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
