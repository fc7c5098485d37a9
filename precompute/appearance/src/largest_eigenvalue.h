#pragma once
// One helper for the relative l2 (spectral) figures of the appearance stage,
// which all come from small Gram matrices.
#include <Eigen/Dense>

#include <algorithm>

namespace phasecast::precompute {

// Largest eigenvalue of a symmetric positive semi-definite Gram matrix
// (|X|_2^2 for G = X^T X), round-off below 0 clamped; 0 for an empty one.
inline double largest_eigenvalue(const Eigen::MatrixXd& gram) {
  if (gram.size() == 0) return 0;
  return std::max(
      0.0,
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(gram, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff());
}

}  // namespace phasecast::precompute
