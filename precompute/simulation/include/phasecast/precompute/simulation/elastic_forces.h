#pragma once
// Elastic forces and their stiffness of every element of a DeformableModel.
// The stiffness is a positive semi-definite approximation of the energy
// Hessian (fixed rotation for co-rotational elements, Gauss-Newton for
// bending), so the implicit step's system matrix stays symmetric positive
// definite and a sparse Cholesky factorization always succeeds.

#include "phasecast/precompute/simulation/deformable_model.h"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace phasecast::precompute {

struct ElasticEvaluation {
  double energy = 0;                              // J
  Eigen::VectorXd force;                          // 3V: -dE/dx
  std::vector<Eigen::Triplet<double>> stiffness;  // 3V x 3V PSD approximation of d2E/dx2
};

// Evaluates every elastic element at positions `x` (3V). Stiffness triplets are
// produced only when `with_stiffness` is set.
ElasticEvaluation evaluate_elastic(const DeformableModel& model, const Eigen::VectorXd& x,
                                   bool with_stiffness);

// Signed dihedral angle of hinge (x0, x1 shared edge; x2, x3 opposite), rad.
double dihedral_angle(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                      const Eigen::Vector3d& x3);

}  // namespace phasecast::precompute
