#pragma once
// Self-collision of deformable surfaces: proximity repulsion with velocity
// filtering (after Bridson et al. 2002). Candidate vertex-triangle and
// edge-edge pairs come from spatial hashes over the swept positions of the
// step; each pair whose predicted end-of-step distance would fall below the
// thickness receives an inelastic impulse along its separating direction
// (Gauss-Seidel, a few sweeps).

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace phasecast::precompute {

// Closest point on triangle (a, b, c) to p, as barycentric weights.
Eigen::Vector3d closest_barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// Whether two triangles that share no vertex intersect (closed triangles,
// orientation tests in double precision).
bool triangles_intersect(const std::array<Eigen::Vector3d, 3>& t, const std::array<Eigen::Vector3d, 3>& u);

// Number of intersecting pairs of triangles that share no vertex. x: 3V, triangles F x 3.
int count_intersecting_pairs(const Eigen::VectorXd& x, const Eigen::MatrixXi& triangles);

class SelfCollision {
 public:
  SelfCollision(Eigen::MatrixXi triangles, double thickness, int sweeps = 4);

  // Changes the step velocities v (3V) so that moving from x0 for h seconds
  // keeps every vertex `thickness` away from the triangles not incident to it.
  // Pinned vertices (inverse mass 0) are never changed.
  void filter(const Eigen::VectorXd& x0, Eigen::VectorXd& v, double h,
              const Eigen::VectorXd& inverse_mass) const;

 private:
  struct Pairs {
    std::vector<std::pair<int, int>> vertex_triangle;
    std::vector<std::pair<int, int>> edge_edge;
  };
  Pairs candidates(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) const;
  bool repel(const std::array<int, 4>& idx, const std::array<double, 4>& weight, const Eigen::Vector3d& n,
             double d0, Eigen::VectorXd& v, double h, const Eigen::VectorXd& inverse_mass) const;
  Eigen::MatrixXi triangles_;
  std::vector<std::array<int, 2>> edges_;
  double thickness_;
  int sweeps_;
  int vertex_count_ = 0;
};

}  // namespace phasecast::precompute
