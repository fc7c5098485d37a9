#pragma once
// Row-major Eigen aliases: package datasets are row-major (HDF5 and NumPy
// order), so these map onto them without transposes.

#include <Eigen/Core>

#include <cstdint>

namespace phasecast {

template <class T>
using RowMatrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

using MatrixXfR = RowMatrix<float>;
using MatrixXiR = RowMatrix<std::int32_t>;
using MatrixXuR = RowMatrix<std::uint32_t>;
using MatrixXbR = RowMatrix<std::uint8_t>;
using Eigen::VectorXf;

}  // namespace phasecast
