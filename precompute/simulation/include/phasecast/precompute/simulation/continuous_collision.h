#pragma once
// Continuous collision detection with a fail-safe (after Provot 1997 and
// Bridson et al. 2002, §7). Over the step x0 -> x1 = x0 + h v, every
// vertex-triangle and edge-edge pair whose four points become coplanar (a root
// of the coplanarity cubic) while touching is a collision; each receives an
// inelastic impulse along its normal at the time of contact. Pairs still
// colliding after a few passes merge into impact zones that move with their
// mean velocity (momentum kept), or stay still when a zone holds a pinned
// vertex or would end where the scene forbids (inside an obstacle). Zones only
// grow, so the loop ends, and a start free of intersections gives an end free
// of intersections: the guarantee the proximity filter alone cannot give.

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

namespace phasecast::precompute {

// Earliest time in [0, 1] at which point p meets triangle (a, b, c), all moving
// linearly from their *0 to their *1 positions, within `tolerance` metres.
std::optional<double> vertex_triangle_contact(const std::array<Eigen::Vector3d, 4>& start,
                                              const std::array<Eigen::Vector3d, 4>& end, double tolerance);
// The same for edges (start[0], start[1]) and (start[2], start[3]).
std::optional<double> edge_edge_contact(const std::array<Eigen::Vector3d, 4>& start,
                                        const std::array<Eigen::Vector3d, 4>& end, double tolerance);

// Whether a free vertex may end the step at a position (e.g. outside every obstacle).
using EndAdmissible = std::function<bool(int vertex, const Eigen::Vector3d& end)>;

struct CcdReport {
  int collisions = 0;       // colliding pairs met over the impulse passes
  int zone_vertices = 0;    // vertices the fail-safe moved as impact zones
  int frozen_vertices = 0;  // of those, vertices held still for the step
};

class ContinuousCollision {
 public:
  // separation: relative normal speed times h an impulse leaves between a pair, m.
  // incremental: later detections of a step test only pairs whose vertices
  // moved (detect_moved); false: every detection is whole (the reference it is tested against).
  ContinuousCollision(Eigen::MatrixXi triangles, double separation, int passes = 6, bool incremental = true);

  // Changes the step velocities v (3V) so that moving from x0 for h seconds
  // makes no surface pass through itself and ends every free vertex where
  // `admissible` allows. Pinned vertices (inverse mass 0) keep v = 0.
  CcdReport resolve(const Eigen::VectorXd& x0, Eigen::VectorXd& v, double h,
                    const Eigen::VectorXd& inverse_mass, const EndAdmissible& admissible) const;

  // A pair that meets during the step.
  struct Collision {
    std::array<int, 4> vertex{};
    std::array<double, 4> weight{};  // the contact point difference is sum weight_i x_i
    Eigen::Vector3d normal;          // unit, oriented from the second point towards the first at the start
    bool edge_edge = false;          // else vertex-triangle
    std::array<int, 2> pair{};       // (vertex, triangle) or (edge, edge): detect() lists pairs in this order
  };
  std::vector<Collision> detect(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) const;
  // The same result as detect(x0, x1) when `previous` is detect(x0, x1') and x1
  // differs from x1' only at the vertices marked in `moved`: a pair's result
  // depends on its four vertices alone, so only pairs with a moved vertex are
  // tested again. The impulse passes and zone rounds after the first move few
  // vertices: on the paper plant's resting leaves the full detection was most
  // of a frame.
  std::vector<Collision> detect_moved(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1,
                                      const std::vector<Collision>& previous,
                                      const std::vector<std::uint8_t>& moved) const;

 private:
  std::optional<Collision> test_vertex_triangle(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, int p,
                                                int f) const;
  std::optional<Collision> test_edge_edge(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, int i,
                                          int g) const;

  Eigen::MatrixXi triangles_;
  std::vector<std::array<int, 2>> edges_;
  double separation_;
  int passes_;
  bool incremental_;
  int vertex_count_ = 0;
};

}  // namespace phasecast::precompute
