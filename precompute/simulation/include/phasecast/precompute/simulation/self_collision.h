#pragma once
// Self-collision of deformable surfaces: proximity repulsion with velocity
// filtering (after Bridson et al. 2002). Candidate vertex-triangle and
// edge-edge pairs come from spatial hashes over the swept positions of the
// step; each pair whose predicted end-of-step distance would fall below the
// thickness receives an inelastic impulse along its separating direction
// (Gauss-Seidel, a few sweeps).

#include "phasecast/core/eigen_types.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace phasecast::precompute {

// Closest point on triangle (a, b, c) to p, as barycentric weights.
Eigen::Vector3d closest_barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// Closest points of segments p0p1 and q0q1 as parameters (s, t) along each.
std::pair<double, double> closest_segment_params(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                                 const Eigen::Vector3d& q0, const Eigen::Vector3d& q1);

// Whether two triangles that share no vertex intersect (closed triangles,
// orientation tests in double precision).
bool triangles_intersect(const std::array<Eigen::Vector3d, 3>& t, const std::array<Eigen::Vector3d, 3>& u);

// Number of intersecting pairs of triangles that share no vertex. x: 3V, triangles F x 3.
int count_intersecting_pairs(const Eigen::VectorXd& x, const Eigen::MatrixXi& triangles);

// Self-contact over recorded frames (rows of 3V positions): the measure of
// issue 15's guarantee, where it matters. Close pairs are vertices that share
// no triangle yet lie nearer than `close_distance` (e.g. 2x the thickness).
// A frame is in contact where a surface vertex lies within kHeldContact x the
// thickness of a triangle not incident to it: the self-collision holds such a
// pair at the thickness, so it rests there, not below it. Edge-edge pairs are
// not counted.
constexpr double kHeldContact = 1.1;
struct ContactSummary {
  int frames = 0;
  int frames_intersecting = 0;     // frames with an intersecting triangle pair
  int worst_intersecting = 0;      // most intersecting pairs in one frame
  int frames_close = 0;            // frames with a close non-neighbour pair
  double closest = 0;              // smallest of those distances over all frames, m (infinite: none)
  int frames_in_contact = 0;       // frames with a vertex held against a triangle (above)
  double closest_to_triangle = 0;  // least vertex-triangle distance up to close_distance, m (infinite: none)
};
ContactSummary summarize_contact(const MatrixXfR& positions, const Eigen::MatrixXi& triangles,
                                 double close_distance, double thickness);

// The unique edges (a < b) of a triangle mesh, sorted.
std::vector<std::array<int, 2>> surface_edges(const Eigen::MatrixXi& triangles);

class SelfCollision {
 public:
  // friction: Coulomb's coefficient between surfaces in contact (Bridson et al.
  // 2002): each repulsion impulse also takes up to friction x its normal velocity
  // change off the pair's relative tangential velocity, never reversing it.
  SelfCollision(Eigen::MatrixXi triangles, double thickness, double friction = 0, int sweeps = 4);

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
  double friction_;
  int sweeps_;
  int vertex_count_ = 0;
};

}  // namespace phasecast::precompute
